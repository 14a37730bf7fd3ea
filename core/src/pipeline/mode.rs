//! Fused or staged: how a job runs, chosen by the plan from the scene's size and the function
//! memory budget, so a job models no more than its scene needs.
//!
//! - **Fused** ([`Stage::Render`]): one task per span loads every split, casts the span's camera
//!   rays, traces their shadow rays and shades, all in memory, and writes its pixel block; no hit
//!   record is shuffled. Chosen whenever one task can hold the whole scene.
//! - **Staged** (HORT's dataflow: CastMap, CastReduce, Expand, TraceMap, TraceReduce): only for
//!   scenes one task cannot hold, and then with the fewest splits whose tasks fit the budget.
//!
//! Both run the same stage functions on the same split objects, so they produce the same image
//! and hit buffer, bit for bit, as the monolithic renderer.
//!
//! The memory model ([`task_bytes`]) is deliberately simple and conservative: a fixed runtime
//! allowance, bytes per triangle resident in a task (the stored split object while it is decoded,
//! the decoded BVH and the per-triangle shading data), and what the span costs: a staged task
//! holds every camera sample's records (candidate hits, shadow queries, occlusion keys and their
//! encodings), a fused task only its pixels and one batch of samples at a time.

use super::PipelineError;
use crate::plural::count;
use crate::stage::Stage;
use serde::{Deserialize, Serialize};

/// How a job's tasks are arranged.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ExecutionMode {
    /// Plan, one Render task per span, Combine: no shuffle of hit records.
    Fused,
    /// Plan, HORT's five shuffle stages, Combine.
    Staged,
}

impl ExecutionMode {
    /// The stages a job of this mode runs, in order.
    pub fn stages(self) -> &'static [Stage] {
        match self {
            ExecutionMode::Fused => &Stage::FUSED,
            ExecutionMode::Staged => &Stage::STAGED,
        }
    }

    /// The stages whose tasks the Worker function runs (all but [`Stage::Plan`]), in order.
    pub fn task_stages(self) -> &'static [Stage] {
        &self.stages()[1..]
    }

    /// The stages a job of this mode runs when it traces shadow rays (`shadows`: the scene has a
    /// light some surface can occlude) or not: a staged job without them skips Expand and
    /// TraceMap (TraceReduce shades from the hits alone). Fused jobs run the same stages either
    /// way.
    pub fn stages_with(self, shadows: bool) -> &'static [Stage] {
        match (self, shadows) {
            (ExecutionMode::Staged, false) => &Stage::STAGED_WITHOUT_SHADOWS,
            _ => self.stages(),
        }
    }

    /// The stage whose outputs Combine assembles.
    pub fn pixel_stage(self) -> Stage {
        match self {
            ExecutionMode::Fused => Stage::Render,
            ExecutionMode::Staged => Stage::TraceReduce,
        }
    }

    /// `"fused"` or `"staged"`, as in JSON and on the command line.
    pub fn as_str(self) -> &'static str {
        match self {
            ExecutionMode::Fused => "fused",
            ExecutionMode::Staged => "staged",
        }
    }
}

impl std::fmt::Display for ExecutionMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

impl std::str::FromStr for ExecutionMode {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "fused" => Ok(ExecutionMode::Fused),
            "staged" => Ok(ExecutionMode::Staged),
            other => Err(format!("unknown mode \"{other}\": use fused or staged")),
        }
    }
}

/// Lambda's default memory size, MB: the budget when a request names none.
pub const DEFAULT_MEMORY_MB: u32 = 2048;
/// Memory a task needs besides its scene data and span records: the runtime, the storage
/// client, code and buffers (bytes).
pub const RUNTIME_BYTES: u64 = 96 << 20;
/// Bytes a triangle costs while it is resident in a task: its share of the stored split object
/// (held while decoding), of the decoded BVH (4-wide leaves and nodes) and of the shading data
/// (vertex normals, reflectance, global id).
pub const TRIANGLE_BYTES: u64 = 320;
/// Bytes one camera sample of a span costs a task that holds every sample's records at its
/// peak ([`SpanMemory::Records`]): its candidate hit, shadow queries and occlusion keys, decoded
/// and encoded. A task that renders in batches pays it for one batch at a time.
pub const SAMPLE_BYTES: u64 = 256;
/// Bytes a pixel of its span costs a task that renders in batches ([`SpanMemory::Batches`]) at
/// its peak: its radiance and hit in the band being rendered, and the span's pixel block, raw
/// and encoded. Measured with the task memory counter on the Cornell box rendered as one span
/// (100x100, 960x540 and 1920x1080 at 1 and 16 spp, 320x180 at 1,024 spp; 2026-12): 78 to
/// 80 B/px.
pub const FUSED_PIXEL_BYTES: u64 = 96;

/// The span a task serves: its pixels, the most samples a pixel may get, and whether the
/// adaptive sampler takes them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SpanLoad {
    /// Pixels of the largest span.
    pub pixels: u64,
    /// Samples per pixel (the adaptive sampler's most).
    pub spp: u32,
    /// Whether the adaptive sampler renders the job.
    pub adaptive: bool,
}

impl SpanLoad {
    /// Camera samples of the span (its pixels times the most samples a pixel may get).
    pub fn samples(&self) -> u64 {
        self.pixels.saturating_mul(u64::from(self.spp))
    }
}

/// How a task holds its span's samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SpanMemory {
    /// Every sample's records at once: staged tasks, fused tasks that run the stage functions
    /// in memory (several splits), and fused adaptive tasks (of one split they hold a row's
    /// samples of both passes at once, never more than the span's, so the same bound holds).
    Records,
    /// Its pixels, and one batch of samples at a time: a fused task of one split without the
    /// adaptive sampler, which renders as the monolithic renderer does.
    Batches,
}

impl SpanMemory {
    /// How a task of a `mode` job over `splits` splits holds a span of `load`.
    pub fn of(mode: ExecutionMode, splits: u32, load: SpanLoad) -> Self {
        match (mode, splits, load.adaptive) {
            (ExecutionMode::Fused, 1, false) => SpanMemory::Batches,
            _ => SpanMemory::Records,
        }
    }
}

/// Predicted peak memory of a task holding `triangles` triangles for a span of `load`, held as
/// `memory` says (bytes).
pub fn task_bytes(memory: SpanMemory, triangles: u64, load: SpanLoad) -> u64 {
    let span = match memory {
        SpanMemory::Records => load.samples().saturating_mul(SAMPLE_BYTES),
        // Samples are traced and shaded a batch of whole pixels at a time.
        SpanMemory::Batches => {
            let batch = u64::from(load.spp).max(crate::render::BATCH_SAMPLES as u64);
            load.pixels
                .saturating_mul(FUSED_PIXEL_BYTES)
                .saturating_add(batch.saturating_mul(SAMPLE_BYTES))
        }
    };
    RUNTIME_BYTES
        .saturating_add(triangles.saturating_mul(TRIANGLE_BYTES))
        .saturating_add(span)
}

/// Bytes per pixel Combine holds at its peak whatever it stores: the assembled radiance, the
/// sRGB rows and the PNG being encoded. Measured with the task memory counter on the bundled
/// Cornell box (1024², 2048², 3072²; 2026-12): 36.6 to 39.9 B/px with the runtime included.
pub const COMBINE_PIXEL_BYTES: u64 = 40;
/// Bytes per pixel more when Combine stores the hit buffer (measured: 13 B/px).
pub const COMBINE_HITS_PIXEL_BYTES: u64 = 14;
/// Bytes per pixel more when Combine stores the linear image (measured: 22 to 25 B/px).
pub const COMBINE_LINEAR_PIXEL_BYTES: u64 = 26;

/// Predicted peak memory of the Combine task of a `pixels`-pixel image storing `outputs`
/// (bytes): an upper bound of the measured figures above, the runtime included.
pub fn combine_bytes(pixels: u64, outputs: super::outputs::StoredOutputs) -> u64 {
    let per_pixel = COMBINE_PIXEL_BYTES
        + if outputs.hits {
            COMBINE_HITS_PIXEL_BYTES
        } else {
            0
        }
        + if outputs.linear {
            COMBINE_LINEAR_PIXEL_BYTES
        } else {
            0
        };
    RUNTIME_BYTES.saturating_add(pixels.saturating_mul(per_pixel))
}

/// Refuses an image whose Combine task would not fit `memory_mb`, naming the figures and
/// `--memory-mb`, before any work is done: otherwise every task would run, and Combine would
/// then run out of memory and be retried until the job failed.
pub fn check_combine_memory(
    width: u32,
    height: u32,
    outputs: super::outputs::StoredOutputs,
    memory_mb: u32,
) -> Result<(), PipelineError> {
    let need = combine_bytes(u64::from(width) * u64::from(height), outputs);
    if need <= u64::from(memory_mb) << 20 {
        return Ok(());
    }
    let stored = match (outputs.linear, outputs.hits) {
        (true, true) => "the PNG, the linear image and the hit buffer",
        (true, false) => "the PNG and the linear image",
        (false, true) => "the PNG and the hit buffer",
        (false, false) => "the PNG",
    };
    Err(PipelineError::BadInput(format!(
        "combining a {width}x{height} image ({stored}) would need about {} MB, over \
         --memory-mb {memory_mb}: raise --memory-mb (Lambda allows up to {}), store fewer \
         outputs, or render fewer pixels",
        need.div_ceil(1 << 20),
        hort_aws_quotas::LAMBDA_MEMORY_MB.end()
    )))
}

/// What the plan chose: the mode, the split count and why, in one sentence.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct JobShape {
    /// Fused or staged.
    pub mode: ExecutionMode,
    /// Splits k.
    pub splits: u32,
    /// Why, in one sentence naming the figures (stored in the plan as `mode_reason`).
    pub reason: String,
}

/// Chooses mode and split count for `triangles` triangles, spans of at most `load`, a budget of
/// `memory_mb`, the user's `splits` (if given) and `mode` (if forced). `max_splits` is the most
/// splits the scene allows; `texture_bytes` are held by every task beside its triangles (the
/// scene's textures).
///
/// - `mode` forced: that mode; splits as given, else 1 (fused) or the fewest that fit (staged).
/// - else `splits` = 1: fused; `splits` = K > 1: staged with K splits;
/// - else fused if one task holds the whole scene, otherwise staged with the fewest splits
///   whose tasks fit.
///
/// A task of the chosen shape that does not fit the budget is refused with the figures named.
pub fn choose_shape(
    triangles: u64,
    load: SpanLoad,
    memory_mb: u32,
    splits: Option<u32>,
    mode: Option<ExecutionMode>,
    max_splits: u32,
    texture_bytes: u64,
) -> Result<JobShape, PipelineError> {
    let budget = (u64::from(memory_mb) << 20).saturating_sub(texture_bytes);
    let bytes = |mode: ExecutionMode, k: u32, held: u64| {
        task_bytes(SpanMemory::of(mode, k, load), held, load)
    };
    let staged = |held: u64| task_bytes(SpanMemory::Records, held, load);
    let fits = |k: u64| staged(triangles.div_ceil(k.max(1))) <= budget;
    let mib = |b: u64| b.div_ceil(1 << 20);
    let whole = bytes(ExecutionMode::Fused, 1, triangles);
    let refuse = || {
        let records = staged(0);
        let span = (records > budget).then_some((load.samples(), records));
        too_big(triangles, span, memory_mb, max_splits)
    };
    let fewest = || {
        // Task memory falls as k grows, so the fewest fitting k is found by bisection.
        let (mut lo, mut hi) = (1u64, u64::from(max_splits.max(1)));
        if !fits(hi) {
            return None;
        }
        while lo < hi {
            let mid = (lo + hi) / 2;
            if fits(mid) { hi = mid } else { lo = mid + 1 }
        }
        Some(lo as u32)
    };
    let (mode, k, reason) = match (mode, splits) {
        (Some(ExecutionMode::Fused), k) => {
            let k = k.unwrap_or(1);
            (
                ExecutionMode::Fused,
                k,
                format!(
                    "forced by --mode fused ({} per task)",
                    count(u64::from(k), "split")
                ),
            )
        }
        (Some(ExecutionMode::Staged), Some(k)) => (
            ExecutionMode::Staged,
            k,
            format!("forced by --mode staged with --splits {k}"),
        ),
        (Some(ExecutionMode::Staged), None) => {
            let k = fewest().ok_or_else(refuse)?;
            let reason = format!(
                "forced by --mode staged; {} is the fewest whose tasks fit {memory_mb} MB",
                count(u64::from(k), "split")
            );
            (ExecutionMode::Staged, k, reason)
        }
        (None, Some(1)) => (
            ExecutionMode::Fused,
            1,
            "--splits 1: the whole scene in one split, so every span renders in one task".into(),
        ),
        (None, Some(k)) => (
            ExecutionMode::Staged,
            k,
            format!(
                "--splits {k}: HORT's staged shuffle over {}",
                count(u64::from(k), "split")
            ),
        ),
        (None, None) if whole <= budget => (
            ExecutionMode::Fused,
            1,
            format!(
                "one task holds the whole scene ({}, about {} MB of {memory_mb} MB)",
                count(triangles, "triangle"),
                mib(whole)
            ),
        ),
        (None, None) => {
            let k = fewest().ok_or_else(refuse)?;
            let reason = format!(
                "the whole scene needs about {} MB, over {memory_mb} MB: {k} splits is the fewest whose tasks fit",
                mib(whole)
            );
            (ExecutionMode::Staged, k, reason)
        }
    };
    let held = match mode {
        ExecutionMode::Fused => triangles,
        ExecutionMode::Staged => triangles.div_ceil(u64::from(k.max(1))),
    };
    let memory = SpanMemory::of(mode, k, load);
    let need = task_bytes(memory, held, load);
    if need > budget {
        let span = match memory {
            SpanMemory::Batches => count(load.pixels, "pixel"),
            SpanMemory::Records => count(load.samples(), "sample"),
        };
        return Err(PipelineError::BadInput(format!(
            "a {mode} task of this job would need about {} MB ({}, {span} per span), over --memory-mb {memory_mb}: raise --memory-mb or use more splits",
            mib(need),
            count(held, "triangle")
        )));
    }
    Ok(JobShape {
        mode,
        splits: k,
        reason,
    })
}

/// No split count fits: the scene's triangles, or `span`'s samples and the bytes a task holding
/// them needs, when even a split of no triangles would not fit.
fn too_big(
    triangles: u64,
    span: Option<(u64, u64)>,
    memory_mb: u32,
    max_splits: u32,
) -> PipelineError {
    if let Some((samples, bytes)) = span {
        return PipelineError::BadInput(format!(
            "a staged task holds every sample of its span: with {} a task needs about {} MB, over --memory-mb {memory_mb}: use more spans (--spans), fewer samples, or raise --memory-mb",
            count(samples, "sample"),
            bytes.div_ceil(1 << 20)
        ));
    }
    PipelineError::BadInput(format!(
        "the scene's {} do not fit --memory-mb {memory_mb} even in {max_splits} splits: raise --memory-mb",
        count(triangles, "triangle")
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::StoredOutputs;

    /// The largest image the contract allows (8192x8192) does not fit the default 2048 MB
    /// even as a PNG alone: refused before any work, naming --memory-mb; 8192 MB holds it.
    #[test]
    fn combine_memory_is_checked_before_any_work() {
        let png = StoredOutputs {
            linear: false,
            hits: false,
        };
        let e = check_combine_memory(8192, 8192, png, 2048).unwrap_err();
        assert_eq!(
            e.to_string(),
            "combining a 8192x8192 image (the PNG) would need about 2656 MB, over --memory-mb \
             2048: raise --memory-mb (Lambda allows up to 10240), store fewer outputs, or \
             render fewer pixels"
        );
        assert!(check_combine_memory(8192, 8192, png, 4096).is_ok());
        assert!(check_combine_memory(8192, 8192, StoredOutputs::ALL, 4096).is_err());
        assert!(check_combine_memory(8192, 8192, StoredOutputs::ALL, 8192).is_ok());
        assert!(check_combine_memory(1920, 1080, StoredOutputs::ALL, 512).is_ok());
    }

    fn load(pixels: u64, spp: u32) -> SpanLoad {
        SpanLoad {
            pixels,
            spp,
            adaptive: false,
        }
    }

    fn shape(
        triangles: u64,
        memory_mb: u32,
        splits: Option<u32>,
        mode: Option<ExecutionMode>,
    ) -> Result<(ExecutionMode, u32), String> {
        choose_shape(triangles, load(65_536, 1), memory_mb, splits, mode, 4096, 0)
            .map(|s| (s.mode, s.splits))
            .map_err(|e| e.to_string())
    }

    #[test]
    fn a_large_budget_chooses_fused_and_a_tiny_one_the_fewest_splits_that_fit() {
        use ExecutionMode::*;
        assert_eq!(shape(1_000_000, 2048, None, None), Ok((Fused, 1)));
        // 128 MB leaves a fused task 128 - 96 - 6 (65,536 pixels x 96 B) - 0.25 (a batch of
        // 1,024 samples x 256 B) = 25.75 MB, 84,377 triangles.
        assert_eq!(shape(100_000, 128, None, None), Ok((Staged, 2)));
        assert_eq!(shape(84_377, 128, None, None), Ok((Fused, 1)));
        assert_eq!(shape(84_378, 128, None, None), Ok((Staged, 2)));
        // 1,024 MB: (1024 - 96 - 16) MB / 320 B = 2,988,441 triangles per task.
        assert_eq!(shape(20_000_000, 1024, None, None), Ok((Staged, 7)));
        let fewest = shape(20_000_000, 1024, None, None).unwrap().1 as u64;
        let staged = |k: u64| {
            task_bytes(
                SpanMemory::Records,
                20_000_000u64.div_ceil(k),
                load(65_536, 1),
            )
        };
        assert!(staged(fewest) <= 1024 << 20);
        assert!(staged(fewest - 1) > 1024 << 20);
    }

    #[test]
    fn the_users_counts_and_forced_modes_win_and_their_reasons_say_so() {
        use ExecutionMode::*;
        assert_eq!(shape(100, 2048, Some(1), None), Ok((Fused, 1)));
        assert_eq!(shape(100, 2048, Some(4), None), Ok((Staged, 4)));
        assert_eq!(shape(100, 2048, None, Some(Staged)), Ok((Staged, 1)));
        assert_eq!(shape(100, 2048, Some(3), Some(Fused)), Ok((Fused, 3)));
        let reason = |splits, mode| {
            choose_shape(100_000, load(65_536, 1), 128, splits, mode, 4096, 0)
                .unwrap()
                .reason
        };
        assert_eq!(
            reason(None, None),
            "the whole scene needs about 133 MB, over 128 MB: 2 splits is the fewest whose tasks fit"
        );
        assert_eq!(
            reason(None, Some(Staged)),
            "forced by --mode staged; 2 splits is the fewest whose tasks fit 128 MB"
        );
        assert_eq!(
            reason(Some(2), None),
            "--splits 2: HORT's staged shuffle over 2 splits"
        );
    }

    #[test]
    fn what_cannot_fit_is_refused_with_the_figures() {
        assert_eq!(
            shape(1_000_000, 128, Some(1), None).unwrap_err(),
            "a fused task of this job would need about 408 MB (1000000 triangles, 65536 pixels per span), over --memory-mb 128: raise --memory-mb or use more splits"
        );
        assert_eq!(
            choose_shape(10_000_000_000, load(65_536, 1), 128, None, None, 4096, 0)
                .unwrap_err()
                .to_string(),
            "the scene's 10000000000 triangles do not fit --memory-mb 128 even in 4096 splits: raise --memory-mb"
        );
    }

    /// A fused task of one split traces and shades one batch of samples at a time: its memory
    /// grows with its span's pixels, not their samples, so the bunny at 3840x2160 and 256 spp
    /// renders fused (it was refused when every sample of a span was counted). A task that
    /// holds every sample's records (staged, a fused task of several splits or with the
    /// adaptive sampler) is charged them: the same job forced staged is refused, naming the
    /// samples and `--spans`.
    #[test]
    fn a_fused_task_is_charged_its_pixels_and_one_batch_of_samples() {
        use ExecutionMode::*;
        let span = (3840 * 2160u64).div_ceil(100);
        let choose = |spp, mode| {
            choose_shape(3676, load(span, spp), 2048, None, mode, 3676, 0)
                .map(|s| s.mode)
                .map_err(|e| e.to_string())
        };
        assert_eq!(choose(256, None), Ok(Fused));
        assert_eq!(choose(65_536, None), Ok(Fused));
        let fused = |spp| task_bytes(SpanMemory::Batches, 3676, load(span, spp));
        assert_eq!(fused(1), fused(1024));
        assert_eq!(fused(4096) - fused(1024), 3072 * SAMPLE_BYTES);
        assert_eq!(
            choose(256, Some(Staged)),
            Err("a staged task holds every sample of its span: with 21233664 samples a task needs about 5280 MB, over --memory-mb 2048: use more spans (--spans), fewer samples, or raise --memory-mb".to_owned())
        );
        let adaptive = SpanLoad {
            adaptive: true,
            ..load(span, 256)
        };
        for (mode, splits, load) in [(Fused, 2, load(span, 256)), (Fused, 1, adaptive)] {
            assert_eq!(SpanMemory::of(mode, splits, load), SpanMemory::Records);
        }
        assert_eq!(
            choose_shape(3676, adaptive, 2048, Some(1), None, 3676, 0)
                .unwrap_err()
                .to_string(),
            "a fused task of this job would need about 5282 MB (3676 triangles, 21233664 samples per span), over --memory-mb 2048: raise --memory-mb or use more splits"
        );
    }

    #[test]
    fn modes_name_their_stages_and_parse() {
        assert_eq!(
            ExecutionMode::Fused.task_stages(),
            [Stage::Render, Stage::Combine]
        );
        assert_eq!(ExecutionMode::Staged.stages().len(), 7);
        assert_eq!(
            ExecutionMode::Staged.stages_with(false),
            [
                Stage::Plan,
                Stage::CastMap,
                Stage::CastReduce,
                Stage::TraceReduce,
                Stage::Combine
            ]
        );
        assert_eq!(
            ExecutionMode::Staged.stages_with(true),
            ExecutionMode::Staged.stages()
        );
        assert_eq!(
            ExecutionMode::Fused.stages_with(false),
            ExecutionMode::Fused.stages()
        );
        assert_eq!("fused".parse(), Ok(ExecutionMode::Fused));
        assert_eq!(
            "both".parse::<ExecutionMode>(),
            Err("unknown mode \"both\": use fused or staged".to_owned())
        );
        assert_eq!(
            serde_json::to_string(&ExecutionMode::Staged).unwrap(),
            "\"staged\""
        );
    }
}
