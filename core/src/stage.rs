//! The stage table: the one place that says which stages a job has, in which order, what each
//! is called in object keys, reports and the state machine, and how its tasks are handed out.
//!
//! | stage | name | state | items field | function | fused | staged | round | needs shadows |
//! |---|---|---|---|---|---|---|---|---|
//! | [`Stage::Plan`] | `plan` | `Plan` | - | `PlanFunctionArn` | yes | yes | | |
//! | [`Stage::Partition`] | `partition` | `Partition` | `partition` | `WorkerFunctionArn` | | | | |
//! | [`Stage::Build`] | `build` | `Build` | `build` | `WorkerFunctionArn` | | | | |
//! | [`Stage::Render`] | `render` | `Render` | `render` | `WorkerFunctionArn` | yes | | | |
//! | [`Stage::CastMap`] | `cast-map` | `CastMap` | `cast_map` | `WorkerFunctionArn` | | yes | yes | |
//! | [`Stage::CastReduce`] | `cast-reduce` | `CastReduce` | `cast_reduce` | `WorkerFunctionArn` | | yes | yes | |
//! | [`Stage::Expand`] | `expand` | `Expand` | `expand` | `WorkerFunctionArn` | | yes | yes | yes |
//! | [`Stage::TraceMap`] | `trace-map` | `TraceMap` | `trace_map` | `WorkerFunctionArn` | | yes | yes | yes |
//! | [`Stage::TraceReduce`] | `trace-reduce` | `TraceReduce` | `trace_reduce` | `WorkerFunctionArn` | | yes | yes | |
//! | [`Stage::Combine`] | `combine` | `Combine` | - | `WorkerFunctionArn` | yes | yes | | |
//!
//! The last four columns are [`Stage::role`]: the fused and staged paths, the stages of a staged
//! round (HORT's shuffle, run again for the refined spans of an adaptive job), and the stages a
//! staged job skips when no light can be occluded; every ordered stage list is derived from them
//! ([`Stage::FUSED`], [`Stage::STAGED`], [`Stage::STAGED_WITHOUT_SHADOWS`], [`Stage::ROUND`]).
//!
//! A scene too large for one function is split by tasks first (Partition, then Build, with the
//! Plan function's `Cut` and `PlanFromParts` steps between and after them; see
//! [`crate::pipeline::partition`]); the plan itself does not list those stages.
//! A job runs either the fused path (Plan, Render, Combine) or HORT's staged path (Plan,
//! CastMap to TraceReduce, Combine); [`crate::pipeline::ExecutionMode::stages`] lists each.
//! The task count of each stage for a given job is [`crate::pipeline::JobPlan::task_count`],
//! its timeout [`crate::predict::task_timeout_seconds`]. `infra/statemachine.asl.json` spells the same table
//! out for Step Functions; a test of the emulator checks the two agree.

use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

use crate::ids::IdError;

/// One stage of the HORT dataflow, in pipeline order (the derived `Ord` follows that order).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Stage {
    /// Cut the scene into split objects, each with its own BVH, and plan the job's tasks.
    Plan,
    /// A scene split by tasks: one byte range of the scene's files parsed, its triangles
    /// written by spatial bucket.
    Partition,
    /// A scene split by tasks: one split object built from the partitions' records.
    Build,
    /// Fused mode only: one span's whole render (cast, shadow rays, shading) against every
    /// split it loads, with no shuffle in between.
    Render,
    /// Primary rays of one span against one split: candidate hits.
    CastMap,
    /// Nearest candidate per pixel sample.
    CastReduce,
    /// Route visible hits to the splits their shadow rays must be tested against.
    Expand,
    /// Shadow rays of routed hits against one split.
    TraceMap,
    /// Per pixel sample and light, occluded if any split occludes; shade.
    TraceReduce,
    /// Assemble the image.
    Combine,
}

/// Where a stage runs (the last columns of the stage table).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct StageRole {
    /// A fused job runs it.
    pub fused: bool,
    /// A staged job runs it.
    pub staged: bool,
    /// One of a staged round's stages (HORT's shuffle).
    pub round: bool,
    /// Only a job that traces shadow rays runs it.
    pub needs_shadows: bool,
}

/// Which ordered list of [`Stage::ALL`] [`select`] makes.
#[derive(Clone, Copy)]
enum Path {
    Fused,
    Staged,
    StagedWithoutShadows,
    Round,
}

/// The stages of [`Stage::ALL`] on `path`, in order; `N` must be their count (a wrong `N` fails
/// at compile time).
const fn select<const N: usize>(path: Path) -> [Stage; N] {
    let mut out = [Stage::Plan; N];
    let (mut i, mut n) = (0, 0);
    while i < Stage::ALL.len() {
        let stage = Stage::ALL[i];
        let role = stage.role();
        let on = match path {
            Path::Fused => role.fused,
            Path::Staged => role.staged,
            Path::StagedWithoutShadows => role.staged && !role.needs_shadows,
            Path::Round => role.round,
        };
        if on {
            assert!(n < N, "more stages on the path than the array holds");
            out[n] = stage;
            n += 1;
        }
        i += 1;
    }
    assert!(n == N, "fewer stages on the path than the array holds");
    out
}

/// The state machine's name of the function that plans a job.
pub const PLAN_FUNCTION: &str = "PlanFunctionArn";
/// The state machine's name of the function that runs any task of the other stages.
pub const WORKER_FUNCTION: &str = "WorkerFunctionArn";

impl Stage {
    /// Every stage, in pipeline order.
    pub const ALL: [Stage; 10] = [
        Stage::Plan,
        Stage::Partition,
        Stage::Build,
        Stage::Render,
        Stage::CastMap,
        Stage::CastReduce,
        Stage::Expand,
        Stage::TraceMap,
        Stage::TraceReduce,
        Stage::Combine,
    ];

    /// The stages whose tasks the Worker function runs (every stage after [`Stage::Plan`]), in
    /// order.
    pub const TASKS: &'static [Stage] = Stage::ALL.split_at(1).1;

    /// A fused job's stages, in order: Plan, Render, Combine.
    pub const FUSED: [Stage; 3] = select(Path::Fused);

    /// A staged job's stages, in order: Plan, HORT's five, Combine.
    pub const STAGED: [Stage; 7] = select(Path::Staged);

    /// A staged job's stages when no light can be occluded: without Expand and TraceMap.
    pub const STAGED_WITHOUT_SHADOWS: [Stage; 5] = select(Path::StagedWithoutShadows);

    /// The stages of a staged round, in order (HORT's shuffle).
    pub const ROUND: [Stage; 5] = select(Path::Round);

    /// Where the stage runs (the stage table's last columns).
    pub const fn role(self) -> StageRole {
        let (fused, staged, round, needs_shadows) = match self {
            Stage::Plan | Stage::Combine => (true, true, false, false),
            Stage::Partition | Stage::Build => (false, false, false, false),
            Stage::Render => (true, false, false, false),
            Stage::CastMap | Stage::CastReduce | Stage::TraceReduce => (false, true, true, false),
            Stage::Expand | Stage::TraceMap => (false, true, true, true),
        };
        StageRole {
            fused,
            staged,
            round,
            needs_shadows,
        }
    }

    /// The stage's stable kebab-case name, used in object keys, JSON, reports and logs.
    pub const fn as_str(self) -> &'static str {
        match self {
            Stage::Plan => "plan",
            Stage::Partition => "partition",
            Stage::Build => "build",
            Stage::Render => "render",
            Stage::CastMap => "cast-map",
            Stage::CastReduce => "cast-reduce",
            Stage::Expand => "expand",
            Stage::TraceMap => "trace-map",
            Stage::TraceReduce => "trace-reduce",
            Stage::Combine => "combine",
        }
    }

    /// The name of the stage's top-level state in `infra/statemachine.asl.json`.
    pub const fn state_name(self) -> &'static str {
        match self {
            Stage::Plan => "Plan",
            Stage::Partition => "Partition",
            Stage::Build => "Build",
            Stage::Render => "Render",
            Stage::CastMap => "CastMap",
            Stage::CastReduce => "CastReduce",
            Stage::Expand => "Expand",
            Stage::TraceMap => "TraceMap",
            Stage::TraceReduce => "TraceReduce",
            Stage::Combine => "Combine",
        }
    }

    /// For a stage run as a Distributed Map, the field of the Plan function's `items` output that
    /// holds its items file key (`$.plan.items.{field}` in the state machine); `None` for the
    /// stages run as one Task state (plan, combine).
    pub const fn items_field(self) -> Option<&'static str> {
        match self {
            Stage::Partition => Some("partition"),
            Stage::Build => Some("build"),
            Stage::Render => Some("render"),
            Stage::CastMap => Some("cast_map"),
            Stage::CastReduce => Some("cast_reduce"),
            Stage::Expand => Some("expand"),
            Stage::TraceMap => Some("trace_map"),
            Stage::TraceReduce => Some("trace_reduce"),
            Stage::Plan | Stage::Combine => None,
        }
    }

    /// The state machine's name of the function that runs the stage's tasks.
    pub const fn function(self) -> &'static str {
        match self {
            Stage::Plan => PLAN_FUNCTION,
            _ => WORKER_FUNCTION,
        }
    }

    /// The stage of a state path of the top-level machine (`"CastMap"` or
    /// `"CastMap/CastMapTask"` -> [`Stage::CastMap`]); `None` for any other state.
    pub fn of_state(path: &str) -> Option<Stage> {
        let top = path.split('/').next().unwrap_or(path);
        Stage::ALL.into_iter().find(|s| s.state_name() == top)
    }

    /// The Map stage whose rerun loop the top-level state of `path` belongs to (`CastMapLost`,
    /// `CastMapCheck`, `CastMapRerun/…`, `CastMapRound`, `CastMapGiveUp` -> [`Stage::CastMap`]:
    /// the suffixes of [`RERUN_LOOP_STATES`]); `None` for any other state, the stage's own
    /// state included.
    pub fn of_rerun_loop_state(path: &str) -> Option<Stage> {
        let top = path.split('/').next().unwrap_or(path);
        Stage::ALL.into_iter().find(|s| {
            s.items_field().is_some()
                && top
                    .strip_prefix(s.state_name())
                    .is_some_and(|rest| RERUN_LOOP_STATES.contains(&rest))
        })
    }
}

/// The states a Map stage `{Map}` runs after its Map state, by the suffix of their names
/// (`infra/statemachine.asl.json`): `{Map}Lost` (the Plan function collects the lost items from
/// the Map Run's written results), `{Map}Check` (go on, rerun or give up), `{Map}Rerun` (the
/// lost items again), `{Map}Round` (count the round) and `{Map}GiveUp` (the job's failure).
pub const RERUN_LOOP_STATES: [&str; 5] = ["Lost", "Check", "Rerun", "Round", "GiveUp"];

/// True for a Map stage's `{Map}Lost` Task state (a top-level state path): the Plan function's
/// bookkeeping after each Map Run, no task of the stage.
pub fn is_lost_step(path: &str) -> bool {
    !path.contains('/') && path.ends_with("Lost") && Stage::of_rerun_loop_state(path).is_some()
}

impl fmt::Display for Stage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl FromStr for Stage {
    type Err = IdError;
    /// Accepts exactly the names [`Stage::as_str`] returns (case-sensitive).
    fn from_str(s: &str) -> Result<Self, IdError> {
        Stage::ALL
            .into_iter()
            .find(|stage| stage.as_str() == s)
            .ok_or_else(|| IdError::UnknownStage {
                found: s.to_owned(),
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rerun_loop_states_name_their_stage_and_only_lost_steps_are_lost_steps() {
        assert_eq!(
            Stage::of_rerun_loop_state("CastMapLost"),
            Some(Stage::CastMap)
        );
        assert_eq!(
            Stage::of_rerun_loop_state("TraceMapRerun/TraceMapRerunTask"),
            Some(Stage::TraceMap)
        );
        assert_eq!(
            Stage::of_rerun_loop_state("RenderGiveUp"),
            Some(Stage::Render)
        );
        assert_eq!(Stage::of_rerun_loop_state("CastMap"), None);
        assert_eq!(Stage::of_rerun_loop_state("CastMapFailed"), None);
        assert_eq!(Stage::of_rerun_loop_state("CombineCheck"), None, "no Map");
        assert!(is_lost_step("BuildLost"));
        assert!(!is_lost_step("CastMapRerun/CastMapRerunTaskLost"));
        assert!(!is_lost_step("CombineLost"));
        assert!(!is_lost_step("Lost"));
    }

    #[test]
    fn the_table_is_the_documented_one() {
        let rows: Vec<(&str, &str, Option<&str>, &str)> = Stage::ALL
            .iter()
            .map(|s| (s.as_str(), s.state_name(), s.items_field(), s.function()))
            .collect();
        assert_eq!(
            rows,
            [
                ("plan", "Plan", None, "PlanFunctionArn"),
                (
                    "partition",
                    "Partition",
                    Some("partition"),
                    "WorkerFunctionArn"
                ),
                ("build", "Build", Some("build"), "WorkerFunctionArn"),
                ("render", "Render", Some("render"), "WorkerFunctionArn"),
                ("cast-map", "CastMap", Some("cast_map"), "WorkerFunctionArn"),
                (
                    "cast-reduce",
                    "CastReduce",
                    Some("cast_reduce"),
                    "WorkerFunctionArn"
                ),
                ("expand", "Expand", Some("expand"), "WorkerFunctionArn"),
                (
                    "trace-map",
                    "TraceMap",
                    Some("trace_map"),
                    "WorkerFunctionArn"
                ),
                (
                    "trace-reduce",
                    "TraceReduce",
                    Some("trace_reduce"),
                    "WorkerFunctionArn"
                ),
                ("combine", "Combine", None, "WorkerFunctionArn"),
            ]
        );
        assert_eq!(Stage::TASKS, &Stage::ALL[1..]);
        assert!(Stage::ALL.windows(2).all(|w| w[0] < w[1]));
    }

    #[test]
    fn names_round_trip_and_are_exact() {
        for stage in Stage::ALL {
            assert_eq!(stage.as_str().parse::<Stage>(), Ok(stage));
            assert_eq!(
                serde_json::to_string(&stage).unwrap(),
                format!("\"{}\"", stage.as_str())
            );
            assert_eq!(Stage::of_state(stage.state_name()), Some(stage));
        }
        assert_eq!(
            "Split".parse::<Stage>().unwrap_err().to_string(),
            "unknown stage \"Split\": expected one of plan, partition, build, render, cast-map, cast-reduce, expand, \
             trace-map, trace-reduce, combine"
        );
        assert!(serde_json::from_str::<Stage>("\"cast_map\"").is_err());
        assert_eq!(
            Stage::of_state("TraceMap/TraceMapTask"),
            Some(Stage::TraceMap)
        );
        assert_eq!(Stage::of_state("Done"), None);
    }
}
