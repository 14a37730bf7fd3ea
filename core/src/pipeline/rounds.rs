//! The rounds of a staged adaptive job. Round 1 runs the five staged stages over the first
//! pass (ranks `0..base_spp` of every pixel). Its TraceReduce tasks decide per pixel and write,
//! besides the span's pixels, the span's [`super::refine_list::RefineList`]. Then, only if
//! some pixel needs more samples, round 2 runs the same stages over ranks `base_spp..max_spp`
//! of those pixels only, and only for the spans and (span, split) pairs that hold them.
//!
//! Task ids: a round-2 task of a stage is the round-1 task of the same span (and split) plus
//! the stage's round-1 task count, so every task (and every object key) stays distinct, and
//! a missing round-2 block is recomputed from its producer like any other.

use super::mode::ExecutionMode;
use super::plan::JobPlan;
use crate::stage::Stage;

/// The stages a round runs, in order (without the stages a job skips; see
/// [`JobPlan::stages`]).
const ROUND_STAGES: [Stage; 5] = Stage::ROUND;

impl JobPlan {
    /// Whether the job may run a second round: staged with the adaptive sampler. (Fused
    /// adaptive jobs run both passes inside each Render task.)
    pub fn has_second_round(&self) -> bool {
        self.mode == ExecutionMode::Staged && self.adaptive.is_some()
    }

    /// The round (1 or 2) of task `task` of `stage` and its index within the round, the index
    /// of the round-1 task of the same span (and split); `None` when the plan has no such task.
    pub fn round_of(&self, stage: Stage, task: u32) -> Option<(u32, u32)> {
        let n = self.task_count(stage) as u32;
        if task < n {
            Some((1, task))
        } else if self.has_second_round() && ROUND_STAGES.contains(&stage) && task - n < n {
            Some((2, task - n))
        } else {
            None
        }
    }

    /// The id of the task of `stage` at `index` in round `round` (see [`JobPlan::round_of`]).
    pub fn round_task(&self, stage: Stage, index: u32, round: u32) -> u32 {
        if round == 2 {
            index + self.task_count(stage) as u32
        } else {
            index
        }
    }

    /// The split a map task of `stage` (CastMap or TraceMap, either round) reads; `None` for
    /// other stages and tasks the plan does not have.
    pub fn split_of(&self, stage: Stage, task: u32) -> Option<u32> {
        let (_, index) = self.round_of(stage, task)?;
        match stage {
            Stage::CastMap => self.cast_tasks.get(index as usize).map(|t| t.split),
            Stage::TraceMap => self.trace_tasks.get(index as usize).map(|t| t.split),
            _ => None,
        }
    }

    /// `tasks` of `stage` in the order to hand them out: map tasks grouped by the split they
    /// read (then by id), so a warm worker taking consecutive tasks finds its split in its
    /// cache; other stages by id. The order changes no output, only how often splits are
    /// decoded.
    pub fn dispatch_order(&self, stage: Stage, mut tasks: Vec<u32>) -> Vec<u32> {
        tasks.sort_by_key(|&t| (self.split_of(stage, t), t));
        tasks
    }

    /// The tasks of `stage` that round 2 runs when the spans `spans` (ascending) hold pixels to
    /// refine: the span tasks of those spans, their CastMap pairs and TraceMap pairs; none for a
    /// stage the job skips or outside the rounds.
    pub fn round_two_tasks(&self, stage: Stage, spans: &[u32]) -> Vec<u32> {
        if !self.has_second_round() || !self.task_stages().contains(&stage) {
            return Vec::new();
        }
        let of = |span: u32| spans.binary_search(&span).is_ok();
        let ids: Vec<u32> = match stage {
            Stage::CastMap => self
                .cast_tasks
                .iter()
                .filter(|t| of(t.span))
                .map(|t| t.task)
                .collect(),
            Stage::TraceMap => self
                .trace_tasks
                .iter()
                .filter(|t| of(t.span))
                .map(|t| t.task)
                .collect(),
            Stage::CastReduce | Stage::Expand | Stage::TraceReduce => spans.to_vec(),
            _ => Vec::new(),
        };
        ids.into_iter()
            .map(|i| self.round_task(stage, i, 2))
            .collect()
    }
}
