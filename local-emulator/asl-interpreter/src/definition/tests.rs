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
    machine["States"]["TraceMap"]["ResultWriter"] = json!({});
    let err = load_error(machine);
    assert!(
        err.contains("\"TraceMap\"") && err.contains("ResultWriter"),
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
    machine["States"]["Plan"]["ResultSelector"]["x.$"] = json!("$.a[*]");
    let err = load_error(machine);
    assert!(err.contains("\"Plan\"") && err.contains("[*]"), "{err}");

    let err = load_error(
        json!({"StartAt": "S", "States": {"S": {"Type": "Succeed"}}, "TimeoutSeconds": 5}),
    );
    assert!(err.contains("TimeoutSeconds"), "{err}");
    assert!(load("{").unwrap_err().to_string().contains("JSON"));
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
    assert_eq!(map.result_path, crate::paths::ResultPath::Discard);
    let super::State::Task(task) = &map.processor.states["TraceMapTask"] else {
        panic!("TraceMapTask is a Task");
    };
    assert_eq!(task.function, "WorkerFunctionArn");
    assert_eq!(task.retry.len(), 3);
    assert_eq!(task.retry[0].max_attempts, 0);
    assert_eq!(task.retry[0].error_equals, ["Hort.BadInput"]);
    assert!(
        task.retry[1..]
            .iter()
            .all(|r| r.jitter == crate::Jitter::Full)
    );
}
