//! HORT's state machine, `infra/statemachine.asl.json`: the file AWS Step Functions runs and the
//! emulator interprets, compiled into this crate.

use asl_interpreter::{Bucket, DefinitionError, Orchestrator, OrchestratorOptions};
use hort_core::store::BlobStore;

/// The definition's text, exactly as deployed.
pub const HORT_DEFINITION: &str = include_str!("../../infra/statemachine.asl.json");

/// Loads [`HORT_DEFINITION`] with `options`.
pub fn hort_orchestrator(options: OrchestratorOptions) -> Result<Orchestrator, DefinitionError> {
    Orchestrator::new(HORT_DEFINITION, options)
}

/// A bucket as the interpreter sees it: `GetObject` (ItemReader) and `PutObject` (ResultWriter) on the job's store.
pub struct StoreItems<'a>(pub &'a dyn BlobStore);

impl Bucket for StoreItems<'_> {
    fn read_object(&self, key: &str) -> Result<Vec<u8>, String> {
        self.0.get(key).map_err(|e| e.to_string())
    }

    fn write_object(&self, key: &str, bytes: Vec<u8>) -> Result<(), String> {
        self.0.put(key, &bytes).map_err(|e| e.to_string())
    }
}

#[cfg(test)]
mod tests {
    use super::HORT_DEFINITION;
    use hort_core::pipeline::ExecutionMode;
    use hort_core::stage::Stage;
    use serde_json::Value;

    /// The stage of one top-level state as the definition spells it: the state's name, the
    /// `stage` literal it passes to the Worker (`None` for Plan), the function it invokes, and
    /// for a Map state its items key path. The main path goes through each Map stage's
    /// `{Map}Lost` Task (the Plan function's lost step, skipped here) and `{Map}Check` Choice by
    /// its first rule (nothing lost); that Choice's other targets must be
    /// the stage's rerun loop (`{Map}GiveUp`, `{Map}Rerun`), whose Map reruns the same stage
    /// with the same function.
    /// `ChooseScene`, the Choice after Plan, is followed to Partition when the scene is split
    /// `by_tasks`, else to its `Default`.
    /// `ChooseMode`, the Choice before the render stages, is followed to the branch of `mode` (its rule whose
    /// `StringEquals` is the mode, else its `Default`); `ChooseShadows` to its `Default` when the
    /// job has `shadows`, else to its one rule's target.
    fn stage_states(
        machine: &Value,
        mode: ExecutionMode,
        shadows: bool,
        by_tasks: bool,
    ) -> Vec<StageRow> {
        walk(machine, mode, shadows, by_tasks).0
    }

    /// A stage's state name, its `stage` literal, its function and its items key path.
    type StageRow = (String, Option<String>, String, Option<String>);

    /// [`stage_states`], and how many states the path enters, the `Succeed` included.
    fn walk(
        machine: &Value,
        mode: ExecutionMode,
        shadows: bool,
        by_tasks: bool,
    ) -> (Vec<StageRow>, u64) {
        let states = &machine["States"];
        let mut out = Vec::new();
        let mut entered = 0;
        let mut next = machine["StartAt"].as_str();
        while let Some(name) = next {
            entered += 1;
            let state = &states[name];
            match state["Type"].as_str() {
                Some("Task") if name.ends_with("Lost") => {
                    // `{Map}Lost`: the Plan function's lost step for the Map before it.
                    let map = name.strip_suffix("Lost").unwrap();
                    let payload = &state["Parameters"]["Payload"];
                    assert_eq!(payload["step"], "lost", "{name}");
                    assert_eq!(
                        payload["stage"], states[map]["ItemSelector"]["stage"],
                        "{name}"
                    );
                    assert_eq!(states[map]["Next"], name, "{name}");
                    assert_eq!(state["Next"], format!("{map}Check"), "{name}");
                    next = state["Next"].as_str();
                    continue;
                }
                Some("Task") => {
                    let params = &state["Parameters"];
                    out.push((
                        name.to_owned(),
                        params["Payload"]["stage"].as_str().map(str::to_owned),
                        params["FunctionName"].as_str().unwrap().to_owned(),
                        None,
                    ));
                }
                Some("Map") => {
                    let processor = &state["ItemProcessor"];
                    let task = &processor["States"][processor["StartAt"].as_str().unwrap()];
                    out.push((
                        name.to_owned(),
                        state["ItemSelector"]["stage"].as_str().map(str::to_owned),
                        task["Parameters"]["FunctionName"]
                            .as_str()
                            .unwrap()
                            .to_owned(),
                        state["ItemReader"]["Parameters"]["Key.$"]
                            .as_str()
                            .map(str::to_owned),
                    ));
                }
                Some("Choice") if name == "ChooseMode" => {
                    let rules = state["Choices"].as_array().unwrap();
                    assert_eq!(rules[0]["Variable"], "$.plan.mode");
                    next = rules
                        .iter()
                        .find(|r| r["StringEquals"] == mode.as_str())
                        .map_or(state["Default"].as_str(), |r| r["Next"].as_str());
                    continue;
                }
                Some("Choice") if name == "ChooseScene" => {
                    let rules = state["Choices"].as_array().unwrap();
                    assert_eq!(rules[0]["Variable"], "$.plan.items.partition");
                    assert_eq!(rules[0]["IsPresent"], true);
                    next = if by_tasks {
                        rules[0]["Next"].as_str()
                    } else {
                        state["Default"].as_str()
                    };
                    continue;
                }
                Some("Choice") if name == "ChooseRefine" => {
                    // Jobs without a second round (the adaptive path is checked on its own).
                    next = state["Default"].as_str();
                    continue;
                }
                Some("Choice") if name == "ChooseShadows" => {
                    let rules = state["Choices"].as_array().unwrap();
                    assert_eq!(rules[0]["Variable"], "$.plan.shadows");
                    assert_eq!(rules[0]["BooleanEquals"], false);
                    next = if shadows {
                        state["Default"].as_str()
                    } else {
                        rules[0]["Next"].as_str()
                    };
                    continue;
                }
                Some("Choice") => {
                    let map = name
                        .strip_suffix("Check")
                        .expect("a Choice named {Map}Check");
                    let rules = state["Choices"].as_array().unwrap();
                    assert_eq!(rules[0]["Variable"], "$.rerun.lost", "{name}");
                    assert_eq!(rules[0]["NumericEquals"], 0, "{name}");
                    assert_eq!(rules[1]["Next"], format!("{map}GiveUp"), "{name}");
                    assert_eq!(state["Default"], format!("{map}Rerun"), "{name}");
                    let rerun = &states[format!("{map}Rerun")];
                    let task = |m: &Value| {
                        let p = &m["ItemProcessor"];
                        p["States"][p["StartAt"].as_str().unwrap()]["Parameters"]["FunctionName"]
                            .clone()
                    };
                    assert_eq!(
                        rerun["ItemSelector"]["stage"],
                        states[map]["ItemSelector"]["stage"]
                    );
                    assert_eq!(task(rerun), task(&states[map]), "{name}");
                    assert_eq!(
                        states[format!("{map}GiveUp")]["Next"],
                        format!("{map}Failed")
                    );
                    next = rules[0]["Next"].as_str();
                    continue;
                }
                Some("Succeed") => break,
                other => panic!("state {name}: unexpected type {other:?} on the main path"),
            }
            next = state["Next"].as_str();
        }
        (out, entered)
    }

    /// The cost model's count of the states a job enters is the definition's.
    #[test]
    fn the_cost_model_counts_the_states_the_definition_enters() {
        let machine: Value = serde_json::from_str(HORT_DEFINITION).unwrap();
        for mode in [ExecutionMode::Fused, ExecutionMode::Staged] {
            for shadows in [true, false] {
                for by_tasks in [false, true] {
                    let (rows, entered) = walk(&machine, mode, shadows, by_tasks);
                    let maps = rows.iter().filter(|r| r.3.is_some()).count() as u64;
                    let by_task_maps = if by_tasks { 2 } else { 0 };
                    let staged = mode == ExecutionMode::Staged;
                    assert_eq!(
                        hort_core::cost::clean_path_states(maps - by_task_maps, staged, by_tasks),
                        entered,
                        "{mode}, shadows {shadows}, split by tasks {by_tasks}"
                    );
                }
            }
        }
    }

    /// After round 1 of a staged adaptive job, `Refine` calls the Plan function for round 2
    /// (the Plan state's call and answer, plus `round: 2`, stored at `$.plan` again) and
    /// `ChooseRound` runs the staged Maps again only when round 2 has CastMap items.
    #[test]
    fn a_second_round_reruns_the_staged_maps_only_when_planned() {
        let machine: Value = serde_json::from_str(HORT_DEFINITION).unwrap();
        let states = &machine["States"];
        assert_eq!(
            states["TraceReduceCheck"]["Choices"][0]["Next"],
            "ChooseRefine"
        );
        let choose = &states["ChooseRefine"];
        assert_eq!(choose["Choices"][0]["Variable"], "$.plan.refine_after");
        assert_eq!(choose["Choices"][0]["BooleanEquals"], true);
        assert_eq!(choose["Choices"][0]["Next"], "Refine");
        assert_eq!(choose["Default"], "Combine");
        let (plan, refine) = (&states["Plan"], &states["Refine"]);
        let mut payload = plan["Parameters"]["Payload"].clone();
        payload["round"] = 2.into();
        assert_eq!(refine["Parameters"]["Payload"], payload);
        for field in ["Resource", "ResultSelector", "ResultPath", "Retry"] {
            assert_eq!(refine[field], plan[field], "{field}");
        }
        assert_eq!(
            refine["Parameters"]["FunctionName"],
            plan["Parameters"]["FunctionName"]
        );
        assert_eq!(refine["Next"], "ChooseRound");
        assert_eq!(refine["Catch"][0]["Next"], "RefineFailed");
        let round = &states["ChooseRound"];
        assert_eq!(round["Choices"][0]["Variable"], "$.plan.items.cast_map");
        assert_eq!(round["Choices"][0]["IsPresent"], true);
        assert_eq!(round["Choices"][0]["Next"], "CastMap");
        assert_eq!(round["Default"], "Combine");
    }

    #[test]
    fn the_definition_runs_the_stage_table_of_each_mode_in_order() {
        let machine: Value = serde_json::from_str(HORT_DEFINITION).unwrap();
        let row = |s: &Stage| {
            (
                s.state_name().to_owned(),
                (*s != Stage::Plan).then(|| s.as_str().to_owned()),
                format!("${{{}}}", s.function()),
                s.items_field().map(|f| format!("$.plan.items.{f}")),
            )
        };
        let plan_step = |state: &str| {
            let function = format!("${{{}}}", Stage::Plan.function());
            (state.to_owned(), None, function, None)
        };
        let cases = [ExecutionMode::Fused, ExecutionMode::Staged]
            .into_iter()
            .flat_map(|mode| [(mode, true), (mode, false)]);
        for (mode, shadows) in cases {
            let expected: Vec<_> = mode.stages_with(shadows).iter().map(row).collect();
            assert_eq!(
                stage_states(&machine, mode, shadows, false),
                expected,
                "{mode}, shadows {shadows}"
            );
            // A scene split by tasks: Partition, Cut, Build and PlanFromParts after Plan.
            let mut by_tasks = vec![expected[0].clone(), row(&Stage::Partition)];
            by_tasks.push(plan_step("Cut"));
            by_tasks.push(row(&Stage::Build));
            by_tasks.push(plan_step("PlanFromParts"));
            by_tasks.extend_from_slice(&expected[1..]);
            assert_eq!(
                stage_states(&machine, mode, shadows, true),
                by_tasks,
                "{mode}, shadows {shadows}, split by tasks"
            );
        }
        // Every stage of the table is on one of the paths.
        let mut all: Vec<Stage> = ExecutionMode::Fused.stages().to_vec();
        all.extend(ExecutionMode::Staged.stages());
        all.extend([Stage::Partition, Stage::Build]);
        assert!(Stage::ALL.iter().all(|s| all.contains(s)));
    }

    /// The Combine state's timeout is the one a job of several frames is checked against
    /// before it starts ([`hort_core::predict::check_combine_time`]).
    #[test]
    fn the_combine_state_times_out_where_the_frame_limit_says() {
        let machine: Value = serde_json::from_str(HORT_DEFINITION).unwrap();
        let combine = &machine["States"]["Combine"];
        assert_eq!(combine["Type"], "Task");
        assert_eq!(
            combine["TimeoutSeconds"].as_u64(),
            Some(hort_core::predict::COMBINE_TIMEOUT_SECONDS)
        );
    }

    /// The Plan function's `cut` and `finish` steps are the Plan state's call plus `step`, with
    /// its answer stored at `$.plan` again, and its failure state.
    #[test]
    fn the_plan_steps_of_a_scene_split_by_tasks_are_the_plan_state_with_a_step() {
        let machine: Value = serde_json::from_str(HORT_DEFINITION).unwrap();
        let states = &machine["States"];
        let plan = &states["Plan"];
        for (state, step, next) in [
            ("Cut", "cut", "Build"),
            ("PlanFromParts", "finish", "ChooseMode"),
        ] {
            let s = &states[state];
            let mut payload = plan["Parameters"]["Payload"].clone();
            payload["step"] = step.into();
            assert_eq!(s["Parameters"]["Payload"], payload, "{state}");
            for field in ["Resource", "ResultSelector", "ResultPath", "Retry", "Catch"] {
                assert_eq!(s[field], plan[field], "{state} {field}");
            }
            assert_eq!(s["Next"], next, "{state}");
        }
        assert_eq!(plan["Next"], "ChooseScene");
        assert_eq!(states["ChooseScene"]["Default"], "ChooseMode");
    }
}
