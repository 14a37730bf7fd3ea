//! The job plan: everything the stage tasks need besides their input blocks, as serde data
//! stored at `jobs/{job}/plan.json` and read by the orchestrator and every function.

use super::PipelineError;
use super::frame_choice::FrameChoice;
use super::frames::{PlannedFrame, cast_pairs, check_frame_assembly_memory, planned_frames};
use super::mode::{
    DEFAULT_MEMORY_MB, ExecutionMode, JobShape, SpanLoad, SpanMemory, check_combine_memory,
    choose_shape,
};
use super::outputs::StoredOutputs;
use super::split::SplitMode;
use crate::adaptive::AdaptiveSettings;
use crate::bvh::{Aabb, BuildPreset};
use crate::camera::Camera;
use crate::plural::count;
use crate::scene::{CameraSpec, Light, Scene, check_image_size};
use crate::stage::Stage;
use crate::unoccludable::unoccludable_lights;
use glam::Vec3;
use serde::{Deserialize, Serialize};

/// Version of the plan's JSON layout; bump on any change (2: fused or staged `mode`).
pub const PLAN_FORMAT_VERSION: u32 = 2;
/// Most splits a job may have.
pub const MAX_SPLITS: u32 = 4096;
/// Most spans a job may have.
pub const MAX_SPANS: u32 = 10_000;
/// Samples per span when the span count is chosen automatically for a job whose tasks hold
/// every sample's records (staged, or fused over several splits).
const AUTO_SAMPLES_PER_SPAN: u64 = 65_536;
/// Predicted work per task when the span count is chosen automatically for a fused job whose
/// tasks render as the monolithic renderer does (one split), ms at the prediction model's
/// reference rates ([`crate::predict::fused_frame_work_ms`]): 12 times a task's fixed cost in
/// the emulator, and half of it on Lambda (an invocation and three S3 requests). Measured
/// against 65,536 samples per span (`docs/perf/block-sizes.md`).
const AUTO_FUSED_TASK_MS: f64 = 50.0;
/// Most spans an automatic count gives.
const AUTO_MAX_SPANS: u64 = 100;

/// What the user asked for; `None` means choose automatically. Stored inside the job request,
/// so its JSON field names are part of the job request's format.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlanRequest {
    /// Image width in pixels, 1 to 65536.
    pub width: u32,
    /// Image height in pixels, 1 to 65536.
    pub height: u32,
    /// Samples per pixel, 1 to 65536.
    pub spp: u32,
    /// Scene splits k; when `None`, 1 if one task holds the whole scene within `memory_mb`,
    /// else the fewest whose tasks fit (see [`choose_shape`]).
    pub splits: Option<u32>,
    /// Pixel spans s; automatic when `None`: spans of about 50 ms of predicted work when a
    /// fused task of one split renders them, else of about 64k samples; at most 100.
    pub spans: Option<u32>,
    /// How the scene is cut into splits.
    #[serde(rename = "split_mode")]
    pub mode: SplitMode,
    /// Fused or staged, forced; `None` lets the plan choose (see [`choose_shape`]).
    #[serde(rename = "mode", default)]
    pub execution: Option<ExecutionMode>,
    /// Memory of one function, MB (Lambda's setting): no task may need more.
    #[serde(default = "default_memory_mb")]
    pub memory_mb: u32,
    /// The adaptive sampler, its `base_spp` equal to `spp`; `None`: every
    /// pixel gets `spp` samples. Absent from the JSON when `None`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub adaptive: Option<AdaptiveSettings>,
    /// Which outputs Combine stores besides the PNG; all of them when absent from the JSON
    /// (and then left out of it).
    #[serde(default, skip_serializing_if = "StoredOutputs::is_all")]
    pub outputs: StoredOutputs,
    /// Which frame of which camera path the job renders; absent from the JSON for a still
    /// image.
    #[serde(default, skip_serializing_if = "FrameChoice::is_still")]
    pub frame: FrameChoice,
}

impl PlanRequest {
    /// Camera samples of one frame: width x height x spp (with the adaptive sampler, its
    /// first pass's count).
    pub fn samples(&self) -> u64 {
        u64::from(self.width) * u64::from(self.height) * u64::from(self.spp)
    }
}

fn default_memory_mb() -> u32 {
    DEFAULT_MEMORY_MB
}

fn is_zero(v: &u32) -> bool {
    *v == 0
}

fn is_quality(preset: &BuildPreset) -> bool {
    *preset == BuildPreset::Quality
}

/// The BVH build of the split objects of `request` over a scene of `triangles` triangles: the
/// fast preset when a still image without adaptive sampling takes few camera samples per
/// triangle ([`BuildPreset::for_samples`]); else the quality preset, as animations and
/// adaptive jobs may trace many more rays than one frame's base samples through the same
/// split objects. The splitters in memory and by tasks both follow it.
pub fn split_build_preset(request: &PlanRequest, triangles: u64) -> BuildPreset {
    if request.adaptive.is_some() || !request.frame.is_still() {
        return BuildPreset::Quality;
    }
    BuildPreset::for_samples(request.samples(), triangles)
}

/// A contiguous row-major range of pixels `[start, end)`; one reduce task each.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct Span {
    /// First pixel of the span (row-major index from the top-left).
    pub start: u64,
    /// One past the last pixel (exclusive); in a plan, the next span starts here.
    pub end: u64,
}

/// One split's summary: id, triangle count, bounds (the root box of its BVH) and stored size.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SplitInfo {
    /// The split's index, `0..k`.
    pub id: u32,
    /// Triangles in the split.
    pub triangles: u64,
    /// Minimum corner of the split's bounding box, world coordinates.
    pub lo: [f32; 3],
    /// Maximum corner of the split's bounding box, world coordinates.
    pub hi: [f32; 3],
    /// Bytes of the stored split object.
    pub bytes: u64,
}

impl SplitInfo {
    /// The split's bounding box.
    pub fn bounds(&self) -> Aabb {
        Aabb {
            lo: Vec3::from(self.lo),
            hi: Vec3::from(self.hi),
        }
    }
}

/// A CastMap task: the span's primary rays against one split.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct CastTask {
    /// The task's id: its index in [`JobPlan::cast_tasks`].
    pub task: u32,
    /// Index of the span in [`JobPlan::spans`].
    pub span: u32,
    /// Id of the split, `0..k`.
    pub split: u32,
}

/// A TraceMap task: the span's shadow queries routed to one split. Task id = span · k + split.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct TraceTask {
    /// The task's id, `span · k + split`: its index in [`JobPlan::trace_tasks`].
    pub task: u32,
    /// Index of the span in [`JobPlan::spans`].
    pub span: u32,
    /// Id of the split, `0..k`.
    pub split: u32,
}

/// The whole plan of a job.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct JobPlan {
    /// Layout version, [`PLAN_FORMAT_VERSION`] ([`JobPlan::from_json`] rejects others).
    pub format: u32,
    /// Fused (one Render task per span) or staged (HORT's shuffle stages).
    pub mode: ExecutionMode,
    /// Why the plan chose `mode` and the split count, in one sentence with the figures.
    pub mode_reason: String,
    /// The memory budget of one function, MB, that the choice was made for.
    pub memory_mb: u32,
    /// Image width in pixels, 1 to 65536.
    pub width: u32,
    /// Image height in pixels, 1 to 65536.
    pub height: u32,
    /// Samples per pixel, 1 to 65536.
    pub spp: u32,
    /// The camera of the job's frame for this image size ([`FrameChoice::camera`]); every task
    /// rebuilds the same camera rays from it and `frame` ([`JobPlan::ray_camera`]).
    pub camera: CameraSpec,
    /// The animation frame whose sample streams the camera follows; absent from the JSON for
    /// frame 0, so still images keep their plans' bytes.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub frame: u32,
    /// The scene's lights, in scene order; a record's `light` indexes this list.
    pub lights: Vec<Light>,
    /// Constant ambient radiance factor per channel: adds `kd * ambient` to every hit.
    pub ambient: [f32; 3],
    /// Linear RGB radiance of samples that hit nothing.
    pub background: [f32; 3],
    /// Triangles in the whole scene (the sum over the splits).
    pub triangles: u64,
    /// How the scene was cut into splits.
    pub split_mode: SplitMode,
    /// The k splits, in id order (`splits[i].id == i`).
    pub splits: Vec<SplitInfo>,
    /// The s spans, in pixel order; together they cover every pixel exactly once.
    pub spans: Vec<Span>,
    /// Staged mode: every (span, split) pair that can meet, span-major; pairs that cannot are
    /// absent. Empty in fused mode.
    pub cast_tasks: Vec<CastTask>,
    /// Staged mode: every (span, split) pair, span-major. Empty in fused mode.
    pub trace_tasks: Vec<TraceTask>,
    /// The adaptive sampler, when the job uses it (`spp` is its base spp): both passes in each
    /// Render task (fused), or two rounds of the staged stages ([`JobPlan::round_of`]).
    /// Absent from the JSON when `None`, so uniform plans keep their bytes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub adaptive: Option<AdaptiveSettings>,
    /// Indices (ascending) of the lights no surface can occlude
    /// ([`crate::unoccludable::unoccludable_lights`]): Expand routes no shadow query for them,
    /// so they count as unblocked everywhere, as in the monolithic renderer. Absent from the
    /// JSON when empty, so other plans keep their bytes.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub unoccludable_lights: Vec<u32>,
    /// A scene split by tasks (`super::partition`): what its scan found, so that the models
    /// that predict a job count its Partition and Build tasks. Absent from the JSON for a scene
    /// loaded whole, so other plans keep their bytes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scene_parts: Option<ScenePartsShape>,
    /// How the split objects' BVHs are built: [`split_build_preset`] of the request and the
    /// triangle count, which whoever builds them follows; absent from the JSON for the quality
    /// preset.
    #[serde(default, skip_serializing_if = "is_quality")]
    pub bvh_build: BuildPreset,
    /// A plan previewed before its job runs (`hort plan`, the API's dry run): the estimated
    /// fraction of camera samples that hit a surface ([`crate::coverage`]), which the models
    /// scale the hit records and shadow rays by. `None` in a job's own plan (the models then
    /// assume every sample hits); absent from the JSON when `None`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera_hit_estimate: Option<f64>,
    /// Which outputs Combine stores besides the PNG (the request's). Absent from the JSON when
    /// all of them, so other plans keep their bytes.
    #[serde(default, skip_serializing_if = "StoredOutputs::is_all")]
    pub outputs: StoredOutputs,
    /// The scene's diffuse textures, in the scene's order (a split's triangles name them by
    /// their index here). Absent from the JSON when none, so other plans keep their bytes.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub textures: Vec<super::PlannedTexture>,
    /// A job of several frames: each frame's number and camera, in order (`camera`, `frame`
    /// and `cast_tasks` above are then the first frame's); its tasks run against
    /// [`JobPlan::frame_view`]. Empty, and absent from the JSON, for a job of one frame.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub frames: Vec<PlannedFrame>,
}

/// What the scan of a scene split by tasks found, as the prediction models need it.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct ScenePartsShape {
    /// The scene's byte ranges: one Partition task each.
    pub ranges: u32,
    /// Bytes of the scene's OBJ files.
    pub scene_bytes: u64,
    /// Vertex positions the files define.
    pub vertices: u64,
    /// Vertex normals the files define.
    pub normals: u64,
}

impl JobPlan {
    /// Number of splits k.
    pub fn k(&self) -> u32 {
        self.splits.len() as u32
    }

    /// The CastMap tasks of `span`.
    pub fn cast_tasks_of(&self, span: u32) -> impl Iterator<Item = &CastTask> {
        self.cast_tasks.iter().filter(move |t| t.span == span)
    }

    /// The TraceMap task of (span, split).
    pub fn trace_task_id(&self, span: u32, split: u32) -> u32 {
        span * self.k() + split
    }

    /// Number of tasks of `stage` in this plan: one for Plan and Combine; in fused mode one
    /// Render task per span; in staged mode one per CastMap/TraceMap pair and one per span for
    /// the reduce stages and Expand. Stages the job does not run ([`JobPlan::stages`]) have none.
    pub fn task_count(&self, stage: Stage) -> usize {
        if !self.stages().contains(&stage) {
            return 0;
        }
        match stage {
            Stage::CastMap => self.cast_tasks.len(),
            Stage::TraceMap => self.trace_tasks.len(),
            Stage::Render | Stage::CastReduce | Stage::Expand | Stage::TraceReduce => {
                self.spans.len()
            }
            Stage::Combine | Stage::Plan => 1,
            // Run before the plan exists (a scene split by tasks): not the plan's tasks.
            Stage::Partition | Stage::Build => 0,
        }
    }

    /// The stages this job runs, in order: its mode's, without Expand and TraceMap when a
    /// staged job has no lights ([`ExecutionMode::stages_with`]).
    pub fn stages(&self) -> &'static [Stage] {
        self.mode.stages_with(self.has_shadows())
    }

    /// The stages whose tasks the Worker function runs (all but [`Stage::Plan`]), in order.
    pub fn task_stages(&self) -> &'static [Stage] {
        &self.stages()[1..]
    }

    /// Whether the job traces shadow rays: the scene has a light some surface can occlude.
    pub fn has_shadows(&self) -> bool {
        self.lights.len() > self.unoccludable_lights.len()
    }

    /// Whether no surface can occlude light `light` (its shadow rays are not traced).
    pub fn is_unoccludable(&self, light: u32) -> bool {
        self.unoccludable_lights.binary_search(&light).is_ok()
    }

    /// The camera the job's tasks trace: `camera` for this image size, with the sample
    /// streams of `frame`.
    pub fn ray_camera(&self) -> Result<Camera, crate::error::SceneError> {
        Ok(Camera::new(&self.camera, self.width, self.height)?.with_frame(self.frame))
    }

    /// The most samples a pixel may get: `spp`, or the adaptive sampler's `max_spp`.
    pub fn max_spp(&self) -> u32 {
        self.adaptive.map_or(self.spp, |a| a.max_spp)
    }

    /// Total bytes of all split objects (the scene as stored).
    pub fn scene_bytes(&self) -> u64 {
        self.splits.iter().map(|s| s.bytes).sum()
    }

    /// Parses a stored plan, checking its version and internal consistency.
    pub fn from_json(key: &str, bytes: &[u8]) -> Result<JobPlan, PipelineError> {
        let plan: JobPlan = serde_json::from_slice(bytes)
            .map_err(|e| PipelineError::Corrupt(format!("plan {key}: {e}")))?;
        if plan.format != PLAN_FORMAT_VERSION {
            return Err(PipelineError::Corrupt(format!(
                "plan {key}: format {}, this build reads {PLAN_FORMAT_VERSION}",
                plan.format
            )));
        }
        let (k, s) = (plan.splits.len() as u32, plan.spans.len() as u32);
        let fused_with_pairs = plan.mode == ExecutionMode::Fused
            && !(plan.cast_tasks.is_empty() && plan.trace_tasks.is_empty());
        if fused_with_pairs {
            return Err(PipelineError::Corrupt(format!(
                "plan {key}: a fused plan lists staged tasks"
            )));
        }
        let lights = plan.lights.len() as u32;
        let ascending = plan.unoccludable_lights.windows(2).all(|w| w[0] < w[1]);
        if !ascending || plan.unoccludable_lights.iter().any(|&l| l >= lights) {
            return Err(PipelineError::Corrupt(format!(
                "plan {key}: unoccludable_lights must be ascending indices below the light count \
                 {lights}"
            )));
        }
        let task_ok = |span: u32, split: u32| span < s && split < k;
        if !plan.cast_tasks.iter().all(|t| task_ok(t.span, t.split))
            || !plan.trace_tasks.iter().all(|t| task_ok(t.span, t.split))
        {
            return Err(PipelineError::Corrupt(format!(
                "plan {key}: a task names a span or split that does not exist"
            )));
        }
        Ok(plan)
    }
}

/// The shape (mode and split count, see [`choose_shape`]) and span count for `request` on a
/// scene of `triangles` triangles: the given counts after range checks, else automatic (the
/// fewest splits that fit the memory budget; spans of about 50 ms of predicted work each when a
/// fused task of one split renders them, else of about 64k samples; at most 100).
pub fn resolve_counts(
    request: &PlanRequest,
    triangles: u64,
) -> Result<(JobShape, u32), PipelineError> {
    resolve_counts_with(request, triangles, &[])
}

/// [`resolve_counts`] for a scene with `textures`, which every task that shades holds: refused
/// if they leave no room ([`super::check_texture_memory`]), else counted in every task's memory.
pub fn resolve_counts_with(
    request: &PlanRequest,
    triangles: u64,
    textures: &[std::sync::Arc<crate::texture::Texture>],
) -> Result<(JobShape, u32), PipelineError> {
    let texture_bytes = super::check_texture_memory(textures, request.memory_mb)?;
    check_image_size(request.width, request.height, request.spp)?;
    // The most samples a pixel may get sizes the spans and tasks.
    let spp = match request.adaptive {
        Some(a) => {
            a.check()?;
            if a.base_spp != request.spp {
                return Err(PipelineError::BadInput(format!(
                    "adaptive base spp {} differs from spp {}: the first pass takes spp samples",
                    a.base_spp, request.spp
                )));
            }
            check_image_size(request.width, request.height, a.max_spp)?;
            a.max_spp
        }
        None => request.spp,
    };
    let pixels = u64::from(request.width) * u64::from(request.height);
    let max_k = triangles.min(u64::from(MAX_SPLITS)) as u32;
    let max_s = pixels.min(u64::from(MAX_SPANS)) as u32;
    if let Some(k) = request.splits
        && (k == 0 || k > max_k)
    {
        return Err(PipelineError::BadInput(format!(
            "--splits {k} is out of range: the scene has {}, so use 1 to {max_k}",
            count(triangles, "triangle")
        )));
    }
    if let Some(s) = request.spans
        && (s == 0 || s > max_s)
    {
        return Err(PipelineError::BadInput(format!(
            "--spans {s} is out of range: the image has {}, so use 1 to {max_s}",
            count(pixels, "pixel")
        )));
    }
    check_combine_memory(
        request.width,
        request.height,
        request.outputs,
        request.memory_mb,
    )?;
    let load = |s: u32| SpanLoad {
        pixels: pixels.div_ceil(u64::from(s)),
        spp,
        adaptive: request.adaptive.is_some(),
    };
    let shape_for = |s: u32| {
        choose_shape(
            triangles,
            load(s),
            request.memory_mb,
            request.splits,
            request.execution,
            max_k.max(1),
            texture_bytes,
        )
    };
    let auto = |per_span: f64, total: f64| {
        let s = (total / per_span).ceil() as u64;
        s.clamp(1, u64::from(max_s).min(AUTO_MAX_SPANS)) as u32
    };
    let (shape, s) = match request.spans {
        Some(s) => (shape_for(s)?, s),
        None => {
            // Spans by their work when a task renders them as the monolithic renderer does
            // (fused, one split; with the adaptive sampler, its work if every pixel were
            // refined); else (or if that shape is refused) by their samples, whose records a
            // task holds.
            let work = crate::predict::fused_frame_work_ms(pixels, spp, triangles);
            let s = auto(AUTO_FUSED_TASK_MS, work);
            let renders =
                |shape: &JobShape| shape.mode == ExecutionMode::Fused && shape.splits == 1;
            match shape_for(s) {
                Ok(shape) if renders(&shape) => (shape, s),
                _ => {
                    let samples = load(1).samples() as f64;
                    let s = auto(AUTO_SAMPLES_PER_SPAN as f64, samples);
                    (shape_for(s)?, s)
                }
            }
        }
    };
    if request.frame.count > 1 {
        // The largest split is about the scene over k (the splits are cut near even).
        let task_triangles = match shape.mode {
            ExecutionMode::Fused => triangles,
            ExecutionMode::Staged => triangles.div_ceil(u64::from(shape.splits.max(1))),
        };
        let memory = SpanMemory::of(shape.mode, shape.splits, load(s));
        check_frame_assembly_memory(request, (memory, task_triangles), load(s))?;
    }
    Ok((shape, s))
}

/// The plan for `scene` cut into the given splits, with `s` spans, in `shape`'s mode. Staged:
/// in spatial split mode, CastMap pairs whose span cannot see the split's box are left out;
/// naive mode keeps all pairs. Fused: no pairs (one Render task per span).
pub fn plan_job(
    scene: &Scene,
    request: &PlanRequest,
    splits: Vec<SplitInfo>,
    shape: &JobShape,
    s: u32,
) -> Result<JobPlan, PipelineError> {
    let triangles: u64 = splits.iter().map(|split| split.triangles).sum();
    let camera_spec = request.frame.camera(scene, request.width, request.height)?;
    let camera = Camera::new(&camera_spec, request.width, request.height)?;
    let pixels = u64::from(request.width) * u64::from(request.height);
    let spans: Vec<Span> = (0..u64::from(s))
        .map(|i| Span {
            start: i * pixels / u64::from(s),
            end: (i + 1) * pixels / u64::from(s),
        })
        .collect();
    let frames = planned_frames(scene, &request.frame, request.width, request.height)?;
    if !frames.is_empty() && request.adaptive.is_some() {
        return Err(PipelineError::BadInput(format!(
            "adaptive sampling renders one frame per job; render the {} frames one --frame at a \
             time",
            frames.len()
        )));
    }
    let (cast_tasks, trace_tasks) = match shape.mode {
        ExecutionMode::Fused => (Vec::new(), Vec::new()),
        ExecutionMode::Staged => (
            cast_pairs(&camera, request.width, request.mode, &spans, &splits),
            (0..spans.len() as u32)
                .flat_map(|span| splits.iter().map(move |split| (span, split.id)))
                .enumerate()
                .map(|(task, (span, split))| TraceTask {
                    task: task as u32,
                    span,
                    split,
                })
                .collect(),
        ),
    };
    Ok(JobPlan {
        format: PLAN_FORMAT_VERSION,
        mode: shape.mode,
        mode_reason: shape.reason.clone(),
        memory_mb: request.memory_mb,
        width: request.width,
        height: request.height,
        spp: request.spp,
        camera: camera_spec,
        frame: request.frame.index,
        lights: scene.lights.clone(),
        // A scene planned from its splits (its mesh left empty) has no geometry to test.
        unoccludable_lights: if scene.mesh.triangle_count() as u64 == triangles {
            unoccludable_lights(&scene.mesh, &scene.lights)
                .into_iter()
                .enumerate()
                .filter(|(_, free)| *free)
                .map(|(l, _)| l as u32)
                .collect()
        } else {
            Vec::new()
        },
        ambient: scene.ambient,
        background: scene.background,
        triangles,
        split_mode: request.mode,
        splits,
        spans,
        cast_tasks,
        trace_tasks,
        adaptive: request.adaptive,
        scene_parts: None,
        bvh_build: split_build_preset(request, triangles),
        camera_hit_estimate: None,
        outputs: request.outputs,
        frames,
        // The one place a job's textures are hashed for their content keys.
        textures: scene
            .mesh
            .textures
            .iter()
            .map(|t| super::PlannedTexture::of(t))
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn req(splits: Option<u32>, spans: Option<u32>) -> PlanRequest {
        PlanRequest {
            width: 64,
            height: 48,
            spp: 1,
            splits,
            spans,
            mode: SplitMode::Spatial,
            execution: None,
            memory_mb: DEFAULT_MEMORY_MB,
            adaptive: None,
            outputs: StoredOutputs::ALL,
            frame: Default::default(),
        }
    }

    fn counts(request: &PlanRequest, triangles: u64) -> Result<(u32, u32), PipelineError> {
        resolve_counts(request, triangles).map(|(shape, s)| (shape.splits, s))
    }

    /// Automatic spans: those a fused task of one split renders carry about 50 ms of predicted
    /// work each (with the adaptive sampler, at its most samples a pixel); those whose every
    /// sample's records a task holds (staged) about 65,536 samples each; at most 100 either
    /// way.
    #[test]
    fn automatic_spans_are_sized_by_work_fused_and_by_samples_staged() {
        let job = |width, height, spp, execution| PlanRequest {
            width,
            height,
            spp,
            execution,
            ..req(None, None)
        };
        let spans = |request: &PlanRequest| {
            let (shape, s) = resolve_counts(request, 3676).unwrap();
            (shape.mode, s)
        };
        let work = crate::predict::fused_frame_work_ms(320 * 180, 64, 3676);
        assert!((200.0..250.0).contains(&work), "{work}");
        let fused = (work / AUTO_FUSED_TASK_MS).ceil() as u32;
        assert_eq!(fused, 5);
        assert_eq!(
            spans(&job(320, 180, 64, None)),
            (ExecutionMode::Fused, fused)
        );
        // 320 x 180 x 64 / 65,536 = 56.25.
        let staged = Some(ExecutionMode::Staged);
        assert_eq!(
            spans(&job(320, 180, 64, staged)),
            (ExecutionMode::Staged, 57)
        );
        assert_eq!(
            spans(&job(1920, 1080, 64, None)),
            (ExecutionMode::Fused, 100)
        );
        assert_eq!(spans(&job(64, 48, 1, None)), (ExecutionMode::Fused, 1));
        // A fused task of one split renders the adaptive sampler's pixels as the monolithic
        // renderer does: spans by the work of its most samples a pixel (64, as above), not by
        // samples (57).
        let adaptive = PlanRequest {
            spp: 4,
            adaptive: Some(crate::adaptive::AdaptiveSettings {
                base_spp: 4,
                max_spp: 64,
                threshold: 0.01,
            }),
            ..job(320, 180, 4, None)
        };
        assert_eq!(spans(&adaptive), (ExecutionMode::Fused, fused));
        let staged_adaptive = PlanRequest {
            execution: staged,
            ..adaptive
        };
        assert_eq!(spans(&staged_adaptive), (ExecutionMode::Staged, 57));
    }

    #[test]
    fn counts_are_checked_with_clear_messages() {
        assert_eq!(counts(&req(Some(3), Some(7)), 100).unwrap(), (3, 7));
        assert_eq!(counts(&req(None, None), 100).unwrap(), (1, 1));
        assert_eq!(counts(&req(None, None), 1_000_000).unwrap(), (1, 1));
        assert_eq!(
            counts(&req(Some(0), None), 100).unwrap_err().to_string(),
            "--splits 0 is out of range: the scene has 100 triangles, so use 1 to 100"
        );
        assert_eq!(
            counts(&req(Some(101), None), 100).unwrap_err().to_string(),
            "--splits 101 is out of range: the scene has 100 triangles, so use 1 to 100"
        );
        assert_eq!(
            counts(&req(None, Some(10_001)), 100)
                .unwrap_err()
                .to_string(),
            "--spans 10001 is out of range: the image has 3072 pixels, so use 1 to 3072"
        );
    }

    /// One triangle, one pixel: singular; two of each: plural.
    #[test]
    fn counts_of_one_are_singular() {
        assert_eq!(
            counts(&req(Some(2), None), 1).unwrap_err().to_string(),
            "--splits 2 is out of range: the scene has 1 triangle, so use 1 to 1"
        );
        assert_eq!(
            counts(&req(Some(3), None), 2).unwrap_err().to_string(),
            "--splits 3 is out of range: the scene has 2 triangles, so use 1 to 2"
        );
        let pixels = |width, height| PlanRequest {
            width,
            height,
            ..req(None, Some(3))
        };
        assert_eq!(
            counts(&pixels(1, 1), 100).unwrap_err().to_string(),
            "--spans 3 is out of range: the image has 1 pixel, so use 1 to 1"
        );
        assert_eq!(
            counts(&pixels(2, 1), 100).unwrap_err().to_string(),
            "--spans 3 is out of range: the image has 2 pixels, so use 1 to 2"
        );
        let one = SpanLoad {
            pixels: 1,
            spp: 1,
            adaptive: false,
        };
        let staged = choose_shape(
            100,
            one,
            DEFAULT_MEMORY_MB,
            None,
            Some(ExecutionMode::Staged),
            MAX_SPLITS,
            0,
        )
        .unwrap();
        assert_eq!(
            staged.reason,
            format!(
                "forced by --mode staged; 1 split is the fewest whose tasks fit {DEFAULT_MEMORY_MB} MB"
            )
        );
        let reason = choose_shape(100, one, DEFAULT_MEMORY_MB, Some(2), None, MAX_SPLITS, 0)
            .unwrap()
            .reason;
        assert_eq!(reason, "--splits 2: HORT's staged shuffle over 2 splits");
    }

    #[test]
    fn spans_cover_every_pixel_once_and_the_plan_round_trips() {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../scenes/cornell/cornell.json"
        );
        let scene = crate::scene::load_scene(std::path::Path::new(path)).unwrap();
        let triangles = scene.mesh.triangle_count() as u64;
        let preset = split_build_preset(&req(Some(3), Some(7)), triangles);
        let infos =
            super::super::split_scene(&scene.mesh, 3, SplitMode::Spatial, preset, |_, _| {
                Ok::<(), ()>(())
            })
            .unwrap();
        let (shape, _) = resolve_counts(&req(Some(3), Some(7)), 100).unwrap();
        assert_eq!(shape.mode, ExecutionMode::Staged);
        let plan = plan_job(&scene, &req(Some(3), Some(7)), infos, &shape, 7).unwrap();
        assert_eq!(plan.spans.first().unwrap().start, 0);
        assert_eq!(plan.spans.last().unwrap().end, 64 * 48);
        assert!(plan.spans.windows(2).all(|w| w[0].end == w[1].start));
        assert_eq!(plan.trace_tasks.len(), 21);
        assert!(
            plan.trace_tasks
                .iter()
                .all(|t| plan.trace_task_id(t.span, t.split) == t.task)
        );
        let json = serde_json::to_vec(&plan).unwrap();
        assert_eq!(JobPlan::from_json("p", &json).unwrap(), plan);
        let counts: Vec<usize> = Stage::ALL.iter().map(|&st| plan.task_count(st)).collect();
        assert_eq!(counts, [1, 0, 0, 0, plan.cast_tasks.len(), 7, 7, 21, 7, 1]);
        // 64x48 over 7 spans: span 0 holds 438 pixels; cornell has one light.
        assert_eq!(plan.spans[0].end - plan.spans[0].start, 438);
        let e = JobPlan::from_json("jobs/x/plan.json", b"{")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("plan jobs/x/plan.json: "), "{e}");
        // Cornell's light can be occluded; a plan naming a light it lacks is refused.
        assert!(plan.unoccludable_lights.is_empty() && plan.has_shadows());
        for bad in [vec![1], vec![0, 0]] {
            let mut broken = plan.clone();
            broken.unoccludable_lights = bad;
            let json = serde_json::to_vec(&broken).unwrap();
            assert_eq!(
                JobPlan::from_json("p", &json).unwrap_err().to_string(),
                "plan p: unoccludable_lights must be ascending indices below the light count 1"
            );
        }
        // Map tasks are handed out grouped by split, then by id; other stages by id.
        let order = plan.dispatch_order(Stage::TraceMap, (0..21).collect());
        let splits: Vec<u32> = order
            .iter()
            .map(|&t| plan.split_of(Stage::TraceMap, t).unwrap())
            .collect();
        assert!(splits.windows(2).all(|w| w[0] <= w[1]), "{splits:?}");
        assert_eq!(order[..7], [0, 3, 6, 9, 12, 15, 18]);
        assert_eq!(plan.dispatch_order(Stage::Expand, vec![2, 0, 1]), [0, 1, 2]);
        let mut free = plan.clone();
        free.unoccludable_lights = vec![0];
        assert!(!free.has_shadows() && free.is_unoccludable(0));
        assert_eq!(free.task_count(Stage::Expand), 0);
        assert_eq!(free.task_count(Stage::TraceMap), 0);
    }
}
