//! The HORT pipeline: split, cast, reduce, expand, trace, reduce, combine, as pure functions over
//! bytes plus a task runner and an in-process driver over any [`crate::store::BlobStore`].
//!
//! Dataflow for a scene cut into k splits and an image cut into s pixel spans:
//!
//! | stage | tasks | reads | writes |
//! |---|---|---|---|
//! | plan | 1 | scene | k split objects (triangles + BVH), `plan.json` |
//! | render (fused mode only) | one per span | every split | shaded pixels + sample-0 hits (part 0) |
//! | cast-map | one per (span, split) pair whose bounds can meet | split | candidate hits of the span's samples (part = span) |
//! | cast-reduce | one per span | the span's candidates | nearest hit per sample (part 0) |
//! | expand | one per span | the span's hits | shadow queries per split (part = split) |
//! | trace-map | one per (span, split) | queries, split (only if any) | occluded (sample, light) keys (part = span) |
//! | trace-reduce | one per span | hits + occlusion of every split | shaded pixels + sample-0 hits (part 0) |
//! | combine | 1 | every span's pixels | image and hit buffer |
//!
//! A fused job runs plan, render, combine; a staged one plan, cast-map to trace-reduce, combine
//! (see [`ExecutionMode`]). Render runs the staged stage functions in memory, in order.
//!
//! Guarantee: every task's output is a pure function of its inputs, and the nearest hit is
//! chosen by (t, then global triangle id) with the same triangle test as the monolithic
//! renderer, so the image and hit buffer equal the monolithic render's bit for bit for every
//! k, s, split mode, spp and worker count.

mod adaptive_rounds;
mod adaptive_span;
mod driver;
pub mod estimate;
mod frame_choice;
mod frame_request;
#[cfg(test)]
mod frame_tests;
mod frames;
mod frustum;
#[cfg(test)]
mod fused_tests;
mod mode;
mod outputs;
pub mod partition;
mod plan;
mod plan_step;
mod query_order;
mod records;
mod refine_list;
mod rounds;
mod runner;
mod split;
mod split_cache;
mod split_object;
mod stages;
mod textures;

pub use crate::task_metrics::{TaskMetrics, micros, timed};
pub use adaptive_span::render_span_adaptive;
pub use driver::{PipelineOptions, PipelineRun, run_pipeline};
pub use frame_choice::{FrameChoice, Orbit};
pub use frame_request::{FrameRequest, FrameRequestError, FrameSelection};
pub use frames::{PlannedFrame, assembled_frames};
pub use frustum::span_may_meet_box;
pub use mode::{
    DEFAULT_MEMORY_MB, ExecutionMode, FUSED_PIXEL_BYTES, JobShape, RUNTIME_BYTES, SAMPLE_BYTES,
    SpanLoad, SpanMemory, TRIANGLE_BYTES, choose_shape, task_bytes,
};
pub use outputs::{JobOutputs, StoredOutputs, read_frame_outputs, read_outputs};
pub use plan::{
    CastTask, JobPlan, MAX_SPANS, MAX_SPLITS, PLAN_FORMAT_VERSION, PlanRequest, ScenePartsShape,
    Span, SplitInfo, TraceTask, plan_job, resolve_counts, resolve_counts_with, split_build_preset,
};
pub use plan_step::{PlannedJob, plan_into_store, plan_into_store_keeping};
pub use records::{Occluded, PixelBlock, ShadowQuery, SurfaceHit};
/// The shuffle record decoders and encoders, public for the fuzz targets in `fuzz/`.
pub use records::{
    decode_occluded, decode_pixels, decode_queries, decode_surface_hits, encode_occluded,
    encode_pixels, encode_queries, encode_surface_hits,
};
pub use refine_list::{RefineList, decode_refine_list, encode_refine_list};
pub use runner::{
    RebuildSplit, producer_of, refined_spans, run_frame_task, run_task, run_task_cached,
    run_task_with,
};
pub use split::{SplitMode, assign_splits, rebuild_split, split_scene, split_scene_objects};
pub use split_cache::SplitCache;
pub use split_object::{SPLIT_FORMAT_VERSION, SplitObject, decode_split, encode_split};
pub use split_object::{ShadingTable, TriangleShading};
pub use stages::{cast_map, cast_reduce, combine, expand, render_span, trace_map, trace_reduce};
pub use textures::{PlannedTexture, check_texture_memory, decode_planned_texture, texture_objects};

use crate::ErrorType;
use crate::store::StoreError;

/// Why a task or the pipeline failed. `Display` is one line naming the object or field.
#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    /// Storage failed; retryable when the store says so.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// A stored object is corrupt or of the wrong kind (recoverable from lineage for shuffle
    /// blocks).
    #[error("{0}")]
    Corrupt(String),
    /// The request or the plan cannot be executed (not retryable).
    #[error("{0}")]
    BadInput(String),
    /// The scene could not be loaded or viewed.
    #[error(transparent)]
    Scene(#[from] crate::error::SceneError),
}

impl PipelineError {
    /// The error type a function reports for this failure ([`ErrorType::Retryable`] exactly when
    /// [`PipelineError::is_retryable`]).
    pub fn error_type(&self) -> ErrorType {
        if self.is_retryable() {
            ErrorType::Retryable
        } else {
            ErrorType::BadInput
        }
    }

    /// Whether running the same task again may succeed.
    pub fn is_retryable(&self) -> bool {
        match self {
            PipelineError::Store(e) => e.is_retryable(),
            PipelineError::Corrupt(_) => true,
            PipelineError::BadInput(_) | PipelineError::Scene(_) => false,
        }
    }
}
