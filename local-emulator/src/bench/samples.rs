//! `hort bench samples`: single-thread per-sample throughput of the monolithic renderer against
//! Mitsuba 3's `multijitter` timings on the same scenes at the same size and sample count.
//!
//! The Mitsuba side is read, not run: `mitsuba.csv` and `settings.json` of the references
//! folder (`eval/references`, written by `eval/mitsuba_refs.py` on one thread). Ours is
//! [`render`] with one thread at the references' size, after one untimed warm-up render, best
//! of `--repeats` (render time only: no loading or BVH build, as Mitsuba's timing). The ratio is
//! ours in samples per second over Mitsuba's, so above 1 means we are faster per sample. Each
//! row also prints a digest of our image (FNV-1a 64 of the pixels' f32 bits, row-major, RGB), so
//! that two builds can be checked to render the same bits. Ours runs once per kernel width the
//! host has (`x4`, and `x8` with AVX2), so each table holds the narrower width as the baseline
//! of the wider, measured in the same run; the widths must render the same image. A second
//! table splits our time per sample into the renderer's phases, beside Embree on the same rays
//! (`breakdown.rs`).

use super::breakdown;
use super::kernel::compile_harness;
use super::scenes::bundled;
use super::table::{Table, f3};
use crate::eval::mitsuba_csv;
use anyhow::{Context, Result, bail};
use hort_core::bvh::{KernelWidth, available_kernel_widths, force_kernel_width};
use hort_core::image::Image;
use hort_core::render::{RenderSettings, build_scene_bvh, render};
use hort_core::scene::load_scene;
use std::path::{Path, PathBuf};

/// Options of `hort bench samples`.
#[derive(clap::Args, Clone, Debug)]
pub struct SamplesBenchArgs {
    /// Scene manifests; each scene's stem must have `multijitter` rows in `mitsuba.csv`
    /// (default: the bundled bunny, cornell and teapot).
    pub scenes: Vec<PathBuf>,
    /// The folder with `mitsuba.csv` and `settings.json` (default: the bundled
    /// `eval/references`).
    #[arg(long)]
    pub references: Option<PathBuf>,
    /// Samples per pixel; `mitsuba.csv` must have a `multijitter` row at this count.
    #[arg(long, default_value_t = 64, value_parser = clap::value_parser!(u32).range(1..=i64::from(hort_core::scene::MAX_SPP)))]
    pub spp: u32,
    /// Timed renders per scene; the best counts.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=100))]
    pub repeats: u32,
    /// Append the tables to this CSV file.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Do not run Embree even if it is installed.
    #[arg(long)]
    pub no_embree: bool,
    /// Where the compiled Embree harness and its ray files go.
    #[arg(long, default_value = "target/kernel-bench")]
    pub work_dir: PathBuf,
}

/// Runs `hort bench samples`.
pub fn run_samples_bench(args: &SamplesBenchArgs) -> Result<()> {
    let references = args
        .references
        .clone()
        .unwrap_or_else(|| bundled("../eval/references"));
    let (width, height) = reference_size(&references.join("settings.json"))?;
    let csv_path = references.join("mitsuba.csv");
    let csv_text = std::fs::read_to_string(&csv_path)
        .with_context(|| format!("reading {}", csv_path.display()))?;
    let mitsuba = mitsuba_csv::parse(&csv_path.display().to_string(), &csv_text)
        .map_err(anyhow::Error::msg)?;
    let scenes = if args.scenes.is_empty() {
        [
            "bunny/bunny.json",
            "cornell/cornell.json",
            "teapot/teapot.json",
        ]
        .map(bundled)
        .to_vec()
    } else {
        args.scenes.clone()
    };
    let harness = if args.no_embree {
        eprintln!("Embree: skipped (--no-embree)");
        None
    } else {
        std::fs::create_dir_all(&args.work_dir)
            .with_context(|| format!("cannot create {}", args.work_dir.display()))?;
        compile_harness(&args.work_dir)
            .map_err(|e| {
                eprintln!(
                    "Embree unavailable ({e:#}); its columns stay empty \
                     (`bash eval/embree.sh` installs it)"
                )
            })
            .ok()
    };
    let mut breakdowns = Vec::new();
    let settings = RenderSettings {
        width,
        height,
        spp: args.spp,
        threads: 1,
        frame: Default::default(),
    };
    let samples = f64::from(width) * f64::from(height) * f64::from(args.spp);
    let mut table = Table::new(
        &format!(
            "per-sample throughput, 1 thread, {width}x{height}, {} spp (best of {})",
            args.spp, args.repeats
        ),
        &[
            "scene",
            "ours s",
            "ours Msamples/s",
            "mitsuba multijitter s",
            "mitsuba Msamples/s",
            "ratio",
            "image fnv1a",
        ],
    );
    for path in &scenes {
        let name = stem(path)?;
        let theirs = mitsuba
            .iter()
            .find(|p| p.scene == name && p.method == "mitsuba multijitter" && p.spp == args.spp)
            .with_context(|| {
                format!(
                    "{}: no multijitter row for scene {name} at {} spp",
                    csv_path.display(),
                    args.spp
                )
            })?;
        let scene = load_scene(path).with_context(|| format!("loading {}", path.display()))?;
        let bvh = build_scene_bvh(&scene.mesh);
        // One row per kernel width this host runs: the narrower is the baseline the wider is
        // measured against, in the same run. Every width must give the same image.
        let mut first_digest = None;
        for width in available_kernel_widths() {
            force_kernel_width(Some(width));
            let label = format!("{name} {}", width_label(width));
            let warm_up = render(&scene, &bvh, settings)?;
            let digest = image_digest(&warm_up.image);
            if *first_digest.get_or_insert(digest) != digest {
                bail!("{label}: the image differs from the narrower kernels' image");
            }
            let mut best = f64::INFINITY;
            for _ in 0..args.repeats {
                let out = render(&scene, &bvh, settings)?;
                if image_digest(&out.image) != digest {
                    bail!("{label}: two renders of the same settings differ");
                }
                best = best.min(out.render_seconds);
            }
            breakdowns.push(breakdown::measure(
                &label,
                &scene,
                &bvh,
                settings,
                args.repeats,
                best,
                Some(theirs.seconds),
                &warm_up.image.pixels,
                harness.as_deref().map(|h| (h, args.work_dir.as_path())),
            )?);
            let ours = samples / best / 1e6;
            let mitsuba_rate = samples / theirs.seconds / 1e6;
            table.push(vec![
                label,
                format!("{best:.4}"),
                f3(ours),
                format!("{:.4}", theirs.seconds),
                f3(mitsuba_rate),
                f3(ours / mitsuba_rate),
                format!("{digest:016x}"),
            ]);
        }
        force_kernel_width(None);
    }
    for t in [table, breakdown::table(&breakdowns, settings)] {
        t.print();
        if let Some(csv) = &args.csv {
            t.append_csv(csv)?;
        }
    }
    Ok(())
}

/// How a table names a kernel width: `x4` (4-wide), `x8` (8-wide leaves, AVX2) or `x16`
/// (16-wide leaves, AVX-512F).
fn width_label(width: KernelWidth) -> &'static str {
    match width {
        KernelWidth::Four => "x4",
        KernelWidth::Eight => "x8",
        KernelWidth::Sixteen => "x16",
    }
}

/// The `width` and `height` of the references' `settings.json`: the size Mitsuba was timed at.
fn reference_size(path: &Path) -> Result<(u32, u32)> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let json: serde_json::Value =
        serde_json::from_str(&text).with_context(|| format!("{}: not JSON", path.display()))?;
    let max = hort_core::scene::MAX_IMAGE_SIDE;
    let size = |key: &str| -> Result<u32> {
        json.get(key)
            .and_then(serde_json::Value::as_u64)
            .and_then(|v| u32::try_from(v).ok())
            .filter(|v| (1..=max).contains(v))
            .with_context(|| format!("{}: `{key}` is not an integer in 1..={max}", path.display()))
    };
    Ok((size("width")?, size("height")?))
}

/// The scene file's stem, the scene's name in `mitsuba.csv`.
fn stem(path: &Path) -> Result<String> {
    Ok(path
        .file_stem()
        .with_context(|| format!("{}: the scene path names no file", path.display()))?
        .to_string_lossy()
        .into_owned())
}

/// FNV-1a 64 over the little-endian bits of every channel of every pixel, row-major.
fn image_digest(image: &Image) -> u64 {
    let mut h = hort_core::digest::Fnv1a64::new();
    for c in image.pixels.iter().flatten() {
        h.write(&c.to_bits().to_le_bytes());
    }
    h.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn digest_is_fnv1a_of_the_pixel_bits() {
        let mut image = Image::new(1, 1);
        image.pixels[0] = [f32::from_bits(0x6261_6f66), 0.0, 0.0];
        let mut bytes = b"foab".to_vec();
        bytes.extend([0u8; 8]);
        let expected = hort_core::digest::fnv1a64(&bytes);
        assert_eq!(image_digest(&image), expected);
        image.pixels[0][2] = -0.0;
        assert_ne!(image_digest(&image), expected, "-0 and +0 differ in bits");
    }

    #[test]
    fn reference_size_names_the_file_and_key() {
        let dir = std::env::temp_dir().join(format!("hort-samples-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("settings.json");
        std::fs::write(&path, r#"{"width": 320, "height": 180}"#).unwrap();
        assert_eq!(reference_size(&path).unwrap(), (320, 180));
        std::fs::write(&path, r#"{"width": 320, "height": 0}"#).unwrap();
        let e = reference_size(&path).unwrap_err().to_string();
        assert_eq!(
            e,
            format!(
                "{}: `height` is not an integer in 1..=65536",
                path.display()
            )
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }

    /// The bundled references have a multijitter row at 64 spp for each default scene, at the
    /// size of settings.json.
    #[test]
    fn bundled_references_cover_the_default_scenes_at_64_spp() {
        let references = bundled("../eval/references");
        assert_eq!(
            reference_size(&references.join("settings.json")).unwrap(),
            (320, 180)
        );
        let text = std::fs::read_to_string(references.join("mitsuba.csv")).unwrap();
        let rows = mitsuba_csv::parse("mitsuba.csv", &text).unwrap();
        for scene in ["bunny", "cornell", "teapot"] {
            let row = rows
                .iter()
                .find(|p| p.scene == scene && p.method == "mitsuba multijitter" && p.spp == 64);
            assert!(row.is_some_and(|p| p.seconds > 0.0), "{scene}");
        }
    }
}
