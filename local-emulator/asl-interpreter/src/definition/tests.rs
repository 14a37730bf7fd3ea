//! Load errors: everything outside the supported subset is refused, naming state and field.

use serde_json::{Value, json};

use super::load;
use crate::tests::HORT_DEFINITION;

fn load_error(definition: Value) -> String {
    load(&definition.to_string()).unwrap_err().to_string()
}

fn with_state(state: Value) -> Value {
    json!({"StartAt": "S", "States": {"S": state}})
}

#[test]
fn unsupported_states_and_fields_are_named() {
    let err = load_error(with_state(
        json!({"Type": "Parallel", "Branches": [], "End": true}),
    ));
    assert!(
        err.contains("\"S\"") && err.contains("\"Parallel\""),
        "{err}"
    );

    let task = json!({
        "Type": "Task",
        "Resource": "arn:aws:states:::lambda:invoke",
        "Parameters": {"FunctionName": "${F}", "Payload": {}},
        "HeartbeatSeconds": 5,
        "End": true
    });
    let err = load_error(with_state(task));
    assert!(
        err.contains("\"S\"") && err.contains("HeartbeatSeconds"),
        "{err}"
    );

    let task = json!({
        "Type": "Task",
        "Resource": "arn:aws:lambda:us-east-1:1:function:f",
        "End": true
    });
    let err = load_error(with_state(task));
    assert!(err.contains("\"S\"") && err.contains("Resource"), "{err}");

    let mut machine: Value = serde_json::from_str(HORT_DEFINITION).unwrap();
    machine["States"]["CastMap"]["ItemProcessor"]["States"]["CastMapTask"]["Retry"][1]["JitterStrategy"] =
        json!("PARTIAL");
    let err = load_error(machine);
    assert!(
        err.contains("\"CastMap/CastMapTask\"") && err.contains("Retry[1].JitterStrategy"),
        "{err}"
    );

    let mut machine: Value = serde_json::from_str(HORT_DEFINITION).unwrap();
    machine["States"]["TraceMap"]["ItemBatcher"] = json!({"MaxItemsPerBatch": 10});
    let err = load_error(machine);
    assert!(
        err.contains("\"TraceMap\"") && err.contains("ItemBatcher"),
        "{err}"
    );

    let mut machine: Value = serde_json::from_str(HORT_DEFINITION).unwrap();
    machine["States"]["Plan"]["Catch"][0]["Next"] = json!("Nowhere");
    let err = load_error(machine);
    assert!(
        err.contains("\"Plan\"") && err.contains("\"Nowhere\""),
        "{err}"
    );

    let mut machine: Value = serde_json::from_str(HORT_DEFINITION).unwrap();
    machine["States"]["Combine"]["Retry"] = json!([
        {"ErrorEquals": ["States.ALL"]},
        {"ErrorEquals": ["Hort.Retryable"]}
    ]);
    let err = load_error(machine);
    assert!(
        err.contains("\"Combine\"") && err.contains("States.ALL"),
        "{err}"
    );

    let mut machine: Value = serde_json::from_str(HORT_DEFINITION).unwrap();
    machine["States"]["Expand"]["ItemProcessor"]["ProcessorConfig"]["Mode"] = json!("INLINE");
    let err = load_error(machine);
    assert!(
        err.contains("\"Expand\"") && err.contains("INLINE"),
        "{err}"
    );

    let mut machine: Value = serde_json::from_str(HORT_DEFINITION).unwrap();
    machine["States"]["Plan"]["ResultSelector"]["x.$"] = json!("$.a[?(@.x)]");
    let err = load_error(machine);
    assert!(
        err.contains("\"Plan\"") && err.contains("[?(@.x)]"),
        "{err}"
    );

    // A wildcard is for template paths only, never a reference path.
    let mut machine: Value = serde_json::from_str(HORT_DEFINITION).unwrap();
    let rerun = machine["States"]["CastMapRerun"].as_object_mut().unwrap();
    rerun.remove("ItemReader");
    rerun.insert("ItemsPath".into(), json!("$.rerun[*]"));
    let err = load_error(machine);
    assert!(
        err.contains("\"CastMapRerun\"") && err.contains("ItemsPath") && err.contains("[*]"),
        "{err}"
    );

    let mut machine: Value = serde_json::from_str(HORT_DEFINITION).unwrap();
    machine["States"]["CastMapRerun"]["ItemsPath"] = json!("$.rerun.items");
    let err = load_error(machine);
    assert!(
        err.contains("\"CastMapRerun\"") && err.contains("both ItemReader and ItemsPath"),
        "{err}"
    );

    let mut machine: Value = serde_json::from_str(HORT_DEFINITION).unwrap();
    machine["States"]["CastMap"]["ToleratedFailurePercentage"] = json!(100);
    let err = load_error(machine);
    assert!(
        err.contains("\"CastMap\"") && err.contains("ToleratedFailurePercentage"),
        "{err}"
    );

    let err = load_error(
        json!({"StartAt": "S", "States": {"S": {"Type": "Succeed"}}, "TimeoutSeconds": 5}),
    );
    assert!(err.contains("TimeoutSeconds"), "{err}");
    assert!(load("{").unwrap_err().to_string().contains("JSON"));
}

#[test]
fn unsupported_choice_rules_are_named() {
    let choice = |rule: Value| {
        load_error(json!({"StartAt": "C", "States": {
            "C": {"Type": "Choice", "Choices": [rule], "Default": "D"},
            "D": {"Type": "Succeed"}
        }}))
    };
    let err = choice(json!({"Variable": "$.a", "StringLessThan": "x", "Next": "D"}));
    assert!(
        err.contains("\"C\"") && err.contains("Choices[0]") && err.contains("StringLessThan"),
        "{err}"
    );
    let err = choice(json!({"Variable": "$.a", "StringEquals": 3, "Next": "D"}));
    assert!(err.contains("StringEquals must be a string"), "{err}");
    let err = choice(json!({"And": [], "Next": "D"}));
    assert!(err.contains("Choices[0]") && err.contains("And"), "{err}");
    let err = choice(json!({"Variable": "$.a", "IsPresent": 1, "Next": "D"}));
    assert!(err.contains("IsPresent must be true or false"), "{err}");
    let err = choice(json!({"Variable": "$.a", "NumericLessThan": "3", "Next": "D"}));
    assert!(err.contains("NumericLessThan must be a number"), "{err}");
    let err =
        choice(json!({"Variable": "$.a", "IsPresent": true, "NumericEquals": 1, "Next": "D"}));
    assert!(err.contains("exactly one comparison"), "{err}");
    let err = choice(json!({"Variable": "$.a", "IsPresent": true}));
    assert!(err.contains("Next"), "{err}");
    let err = choice(json!({"Variable": "$.a", "IsPresent": true, "Next": "Nowhere"}));
    assert!(err.contains("\"Nowhere\""), "{err}");
    let err = load_error(json!({"StartAt": "C", "States": {
        "C": {"Type": "Choice", "Choices": [], "Default": "C"}
    }}));
    assert!(err.contains("Choices is empty"), "{err}");
}

#[test]
fn the_hort_definition_compiles_to_the_documented_graph() {
    let machine = load(HORT_DEFINITION).unwrap();
    let names: Vec<&str> = machine.states.keys().map(String::as_str).collect();
    for stage in [
        "Plan",
        "CastMap",
        "CastReduce",
        "Expand",
        "TraceMap",
        "TraceReduce",
        "Combine",
    ] {
        assert!(names.contains(&stage), "{stage}");
        assert!(
            names.contains(&format!("{stage}Failed").as_str()),
            "{stage}Failed"
        );
    }
    let super::State::Map(map) = &machine.states["TraceMap"] else {
        panic!("TraceMap is a Map");
    };
    assert!(map.express);
    assert_eq!(
        map.result_path,
        crate::paths::ResultPath::Field(vec!["results".into()], "$.results".into())
    );
    // Every Map stage writes its results to S3, collects its lost items with the Plan
    // function, and reruns them (read from S3 too) in a bounded loop before its Fail state.
    let stages = ["Partition", "Build", "Render", "CastMap", "CastReduce"];
    for stage in stages
        .into_iter()
        .chain(["Expand", "TraceMap", "TraceReduce"])
    {
        let state = |suffix: &str| &machine.states[&format!("{stage}{suffix}")];
        for map in [state(""), state("Rerun")] {
            assert!(
                matches!(map, super::State::Map(m)
                if matches!(m.items, super::Items::Reader(_)) && m.result_writer.is_some()),
                "{stage}"
            );
        }
        assert!(
            matches!(state("Lost"), super::State::Task(t) if t.function == "PlanFunctionArn"),
            "{stage}"
        );
        assert!(matches!(state("Check"), super::State::Choice(_)), "{stage}");
        assert!(matches!(state("Round"), super::State::Pass(_)), "{stage}");
        assert!(matches!(state("GiveUp"), super::State::Pass(_)), "{stage}");
    }
    let super::State::Task(task) = &map.processor.states["TraceMapTask"] else {
        panic!("TraceMapTask is a Task");
    };
    assert_eq!(task.function, "WorkerFunctionArn");
    assert_eq!(task.retry.len(), 4);
    assert_eq!(task.retry[0].max_attempts, 0);
    assert_eq!(task.retry[0].error_equals, ["Hort.BadInput"]);
    assert!(
        task.retry[1..]
            .iter()
            .all(|r| r.jitter == crate::Jitter::Full)
    );
}

/// Found by fuzzing (fuzz/, target `asl`): a field name holding a carriage return or newline
/// was echoed raw, so the error spanned lines. It is escaped.
#[test]
fn control_characters_in_field_names_stay_escaped() {
    let e = load_error(with_state(
        json!({"Type": "Pass", "End": true, "Comm\rent": "x"}),
    ));
    assert!(!e.contains(['\r', '\n']), "{e}");
    assert!(
        e.starts_with(r#"state "S": Comm\rent: unknown field `Comm\rent`, expected one of"#),
        "{e}"
    );
}
