//! The flags that shape a job's plan, shared by `hort render` and `hort plan` (the same names,
//! ranges and defaults, so a plan previewed is the plan rendered), and the one builder of the
//! [`PlanRequest`] from them. The output flags are among them: a job stores the linear image
//! and the hit buffer only when the command writes them, which changes its Combine task and
//! its storage.

use anyhow::Result;
use clap::Args;
use hort_core::adaptive::AdaptiveSettings;
use hort_core::pipeline::{ExecutionMode, PlanRequest, SplitMode, StoredOutputs};
use hort_core::scene::{DEFAULT_HEIGHT, DEFAULT_WIDTH, ImageSettings, check_image_size};
use std::path::{Path, PathBuf};

/// The plan-shaping flags of `hort render` and `hort plan`.
#[derive(Args, Clone, Debug)]
pub struct PlanFlags {
    /// Image width in pixels, 1 to 65536 (default: manifest, else 960).
    #[arg(long, allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(1..=i64::from(hort_core::scene::MAX_IMAGE_SIDE)))]
    pub width: Option<u32>,
    /// Image height in pixels, 1 to 65536 (default: manifest, else 540).
    #[arg(long, allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(1..=i64::from(hort_core::scene::MAX_IMAGE_SIDE)))]
    pub height: Option<u32>,
    /// Samples per pixel, 1 to 65536 (default: manifest, else 1).
    #[arg(long, allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(1..=i64::from(hort_core::scene::MAX_SPP)))]
    pub spp: Option<u32>,
    /// Scene splits k. 1 runs fused (one task renders a span against the whole scene), K > 1
    /// runs HORT's staged shuffle over K splits (default: fused when one function holds the
    /// whole scene within --memory-mb, else staged with the fewest splits that fit).
    #[arg(long, allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(1..))]
    pub splits: Option<u32>,
    /// Pixel spans s, one reduce task each; HORT's d = s x k map inputs (default: fused, about
    /// one per 50 ms of predicted work; staged, one per 64k samples; at most 100).
    #[arg(long, allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(1..))]
    pub spans: Option<u32>,
    /// Force fused (no shuffle) or staged (HORT's map/reduce stages) execution, for tests and
    /// benchmarks; by default the plan chooses from the scene's size and --memory-mb.
    #[arg(long)]
    pub mode: Option<ExecutionMode>,
    /// How the scene is cut: spatial clusters (default) or the paper's naive index ranges.
    #[arg(long, default_value = "spatial")]
    pub split_mode: SplitMode,
    /// Memory of one function, MB, 128 to 10240 as in Lambda: the plan keeps every task within
    /// it (choosing fused or staged and the split count), and the cost estimate assumes it.
    /// Default: the Worker's in infra/template.yaml.
    #[arg(long, default_value_t = hort::deployment::Deployment::bundled().worker.memory_mb, allow_negative_numbers = true, value_parser = clap::value_parser!(u32).range(128..=10240))]
    pub memory_mb: u32,
    /// Split the scene by tasks (partition tasks over byte ranges of its OBJ files, then one
    /// build task per split) in ranges of this many bytes, whatever its size (default: only a
    /// scene too large for one function to load within --memory-mb is, in ranges of a
    /// sixteenth of it).
    #[arg(long, value_name = "BYTES", value_parser = clap::value_parser!(u64).range(1..))]
    pub scene_range_bytes: Option<u64>,
}

/// An image's size and samples per pixel, resolved.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ImageSize {
    /// Pixels across.
    pub width: u32,
    /// Pixels down.
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
}

impl PlanFlags {
    /// The image size and samples: each flag, else the scene manifest's `image` setting, else
    /// the default; checked against the image limits.
    pub fn image_size(&self, image: &ImageSettings) -> Result<ImageSize> {
        let size = ImageSize {
            width: self.width.or(image.width).unwrap_or(DEFAULT_WIDTH),
            height: self.height.or(image.height).unwrap_or(DEFAULT_HEIGHT),
            spp: self.spp.or(image.spp).unwrap_or(1),
        };
        check_image_size(size.width, size.height, size.spp)?;
        Ok(size)
    }

    /// The job request's `render` for an image of `size`, with the adaptive sampler's settings
    /// and the outputs to store.
    pub fn request(
        &self,
        size: ImageSize,
        adaptive: Option<AdaptiveSettings>,
        outputs: StoredOutputs,
    ) -> PlanRequest {
        PlanRequest {
            width: size.width,
            height: size.height,
            spp: size.spp,
            splits: self.splits,
            spans: self.spans,
            mode: self.split_mode,
            execution: self.mode,
            memory_mb: self.memory_mb,
            adaptive,
            outputs,
            frame: Default::default(),
        }
    }
}

/// The output flags of `hort render`, which `hort plan` takes too: what they name decides the
/// outputs the job stores.
#[derive(Args, Clone, Debug, Default)]
pub struct OutputFlags {
    /// Output image: .png or .jpg (8-bit sRGB), .pfm or .exr (linear). Default: the scene file's
    /// name with .png, in the current folder. `hort render` checks it before any work and writes
    /// it atomically; `hort plan` writes nothing and plans the job that stores it.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Write the hit buffer: per pixel a little-endian {u32 triangle, f32 t} (`hort plan`: plan
    /// the job that stores it).
    #[arg(long)]
    pub hits: Option<PathBuf>,
}

impl OutputFlags {
    /// What a job writing these outputs stores besides its PNG: the linear image unless the
    /// image is a PNG (the default), and the hit buffer when asked for.
    pub fn stored(&self) -> StoredOutputs {
        StoredOutputs {
            linear: self.out.as_deref().is_some_and(|out| !is_png(out)),
            hits: self.hits.is_some(),
        }
    }
}

/// Whether `out` names a PNG file (the one image a job stores ready to write).
pub fn is_png(out: &Path) -> bool {
    out.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("png"))
}
