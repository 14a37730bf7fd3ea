//! The frames of a job of several frames: each frame's camera in the plan, and the view of the
//! plan one frame's tasks run against. A frame's tasks are the tasks of a job of that frame
//! alone (the same camera, sample streams and CastMap pairs), so frame K of a job is frame K
//! rendered alone, byte for byte; only their keys differ ([`crate::keys::FrameKeys`]).

use super::PipelineError;
use super::frame_choice::FrameChoice;
use super::frustum::span_may_meet_box;
use super::mode::{ExecutionMode, RUNTIME_BYTES, SpanLoad, SpanMemory, combine_bytes, task_bytes};
use super::plan::{CastTask, JobPlan, Span, SplitInfo};
use super::split::SplitMode;
use crate::camera::Camera;
use crate::ids::JobId;
use crate::scene::{CameraSpec, Scene};
use crate::stage::Stage;
use crate::store::{BlobStore, StoreError};
use serde::{Deserialize, Serialize};
use std::borrow::Cow;

/// One frame of a job of several frames.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlannedFrame {
    /// The frame's number: its sample streams and its keys.
    pub frame: u32,
    /// The frame's camera for the job's image size.
    pub camera: CameraSpec,
}

/// The frames `choice` asks of `scene` at `width` x `height`, each camera checked: empty for a
/// job of one frame (the plan's own camera is then the frame's).
pub(super) fn planned_frames(
    scene: &Scene,
    choice: &FrameChoice,
    width: u32,
    height: u32,
) -> Result<Vec<PlannedFrame>, PipelineError> {
    if choice.count <= 1 {
        return Ok(Vec::new());
    }
    choice
        .frames()
        .map(|frame| {
            let camera = choice.at(frame).camera(scene, width, height)?;
            Camera::new(&camera, width, height)?;
            Ok(PlannedFrame { frame, camera })
        })
        .collect()
}

/// Refuses a job of several frames whose pixel-stage task, which also assembles its frame when
/// it finishes one, would not fit `memory_mb` as the memory model puts it: the largest such
/// task ([`task_bytes`] of its triangles and span) plus Combine's hold of the frame
/// ([`combine_bytes`], its runtime counted once).
pub(super) fn check_frame_assembly_memory(
    request: &super::PlanRequest,
    (memory, task_triangles): (SpanMemory, u64),
    load: SpanLoad,
) -> Result<(), PipelineError> {
    let pixels = u64::from(request.width) * u64::from(request.height);
    let need = task_bytes(memory, task_triangles, load)
        .saturating_add(combine_bytes(pixels, request.outputs).saturating_sub(RUNTIME_BYTES));
    if need <= u64::from(request.memory_mb) << 20 {
        return Ok(());
    }
    Err(PipelineError::BadInput(format!(
        "a task that finishes a frame also assembles it: rendering and assembling a {}x{} \
         frame would need about {} MB, over --memory-mb {}: raise --memory-mb, store fewer \
         outputs, or render fewer pixels",
        request.width,
        request.height,
        need.div_ceil(1 << 20),
        request.memory_mb
    )))
}

/// The CastMap pairs of a staged job seen by `camera`: every (span, split) pair, span-major,
/// whose span can see the split's box (every pair in naive split mode), numbered in order.
pub(super) fn cast_pairs(
    camera: &Camera,
    width: u32,
    mode: SplitMode,
    spans: &[Span],
    splits: &[SplitInfo],
) -> Vec<CastTask> {
    let mut tasks = Vec::new();
    for (span_index, span) in spans.iter().enumerate() {
        for split in splits {
            if mode == SplitMode::Naive || span_may_meet_box(camera, width, span, &split.bounds()) {
                tasks.push(CastTask {
                    task: tasks.len() as u32,
                    span: span_index as u32,
                    split: split.id,
                });
            }
        }
    }
    tasks
}

/// The frames of a job of several frames whose PNG is stored (their outputs are complete: the
/// PNG is written last), from one listing of the job's frames: the frames done so far.
pub fn assembled_frames(
    store: &dyn BlobStore,
    job: &JobId,
) -> Result<std::collections::BTreeSet<u32>, StoreError> {
    let prefix = format!("jobs/{job}/frames/");
    let listed = store.list(&prefix)?;
    Ok(listed
        .iter()
        .filter_map(|key| {
            let (frame, rest) = key.strip_prefix(&prefix)?.split_once('/')?;
            (rest == "out/image.png").then(|| frame.parse().ok())?
        })
        .collect())
}

impl JobPlan {
    /// The frames whose tasks the job runs: `[None]` for a job of one frame, else each
    /// frame's number, in order.
    pub fn frame_numbers(&self) -> Vec<Option<u32>> {
        if self.frames.is_empty() {
            vec![None]
        } else {
            self.frames.iter().map(|f| Some(f.frame)).collect()
        }
    }

    /// Every task of `stage` (round 1's), each with its frame in a job of several frames: frame
    /// after frame (so the first frames finish first), each frame's tasks in their dispatch
    /// order. Combine is one task, named without a frame (it combines every frame).
    pub fn frame_tasks(&self, stage: Stage) -> Result<Vec<(Option<u32>, u32)>, PipelineError> {
        if stage == Stage::Combine {
            return Ok(vec![(None, 0)]);
        }
        let mut tasks = Vec::new();
        for frame in self.frame_numbers() {
            let view = self.frame_view(frame)?;
            let order = view.dispatch_order(stage, (0..view.task_count(stage) as u32).collect());
            tasks.extend(order.into_iter().map(|task| (frame, task)));
        }
        Ok(tasks)
    }

    /// The tasks of `stage` over all the job's frames (round 1's): [`JobPlan::task_count`] of
    /// every frame's view, but one Plan and one Combine task (it combines every frame).
    pub fn job_task_count(&self, stage: Stage) -> usize {
        if self.frames.is_empty() || matches!(stage, Stage::Combine | Stage::Plan) {
            return self.task_count(stage);
        }
        self.frame_numbers()
            .into_iter()
            .filter_map(|frame| self.frame_view(frame).ok())
            .map(|view| view.task_count(stage))
            .sum()
    }

    /// The plan frame `frame`'s tasks run against: this plan for a job of one frame
    /// (`frame` `None`), else the plan of that frame alone (its camera, sample streams and
    /// CastMap pairs; no frame list). Errors when `frame` is not one of the job's.
    pub fn frame_view(&self, frame: Option<u32>) -> Result<Cow<'_, JobPlan>, PipelineError> {
        let wrong = |what: String| PipelineError::BadInput(what);
        match (frame, self.frames.is_empty()) {
            (None, true) => Ok(Cow::Borrowed(self)),
            (None, false) => Err(wrong(format!(
                "the job renders {} frames: a task must name its frame",
                self.frames.len()
            ))),
            (Some(k), true) => Err(wrong(format!(
                "frame {k}: the job renders one frame, and its tasks name none"
            ))),
            (Some(k), false) => {
                let planned = self.frames.iter().find(|f| f.frame == k).ok_or_else(|| {
                    let (first, last) = (
                        self.frames[0].frame,
                        self.frames[self.frames.len() - 1].frame,
                    );
                    wrong(format!(
                        "frame {k} is not one of the job's frames ({first} to {last})"
                    ))
                })?;
                let camera = Camera::new(&planned.camera, self.width, self.height)?;
                let cast_tasks = match self.mode {
                    ExecutionMode::Fused => Vec::new(),
                    ExecutionMode::Staged => cast_pairs(
                        &camera,
                        self.width,
                        self.split_mode,
                        &self.spans,
                        &self.splits,
                    ),
                };
                Ok(Cow::Owned(JobPlan {
                    camera: planned.camera,
                    frame: planned.frame,
                    cast_tasks,
                    frames: Vec::new(),
                    ..self.clone()
                }))
            }
        }
    }
}
