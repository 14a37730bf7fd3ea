//! `hort bench kernel`: single-thread ray throughput of our BVH kernel against native Embree on
//! the identical rays, plus BVH build and split-object load times.
//!
//! Per scene: one primary ray per pixel centre (exactly the renderer's camera rays), traced
//! with [`Bvh::closest_hit`]; for each primary hit, the shadow ray towards the scene's first
//! light exactly as the renderer builds it ([`shadow_test`]), traced with [`Bvh::occluded`].
//! All rays and our answers go to a binary file that `bench/embree_harness.c` (compiled here at
//! run time against `libembree3` when it is installed) traces with `rtcIntersect1`,
//! `rtcIntersect16` and `rtcOccluded1` on a one-thread device. The rays come in the renderer's
//! tile order (4x4 pixel tiles left to right in bands of four rows), so the harness's groups of
//! 16 consecutive rays for `rtcIntersect16` are one tile each. Our coherent path
//! ([`Bvh::closest_hits`]) traces the same primary rays in its packets of
//! [`CLOSEST_PACKET`](hort_core::bvh::CLOSEST_PACKET) consecutive rays (two tiles side by
//! side) and must return the single-ray answers; the shadow rays go through
//! [`Bvh::occluded_many`], in packets of [`RAY_PACKET`](hort_core::bvh::RAY_PACKET). With
//! `--features obvhs-bench`, the crate obvhs runs on the same rays too (`obvhs_kernel.rs`).
//! Timings are the best of `--repeats` passes; ratios compare numbers measured in the same
//! run. A third table times the whole monolithic render at the same size,
//! one sample per pixel, beside Embree on the rays it traces (`whole_render.rs`).

use super::scenes::{bundled, generated};
use super::table::{Table, f3};
use super::timing::{best_of, best_of_prepared};
use anyhow::{Context, Result, bail};
use hort_core::bvh::Bvh;
use hort_core::camera::Camera;
use hort_core::pipeline::{SplitObject, decode_split, encode_split};
use hort_core::render::{band_runs, shading_of, surface_of};
use hort_core::scene::{Scene, load_scene};
use hort_core::shading::shadow_test;
use hort_core::tiles::tile_order;
use hort_core::triangle::Ray;
use hort_core::worker_pool::available_cores;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Options of `hort bench kernel`.
#[derive(clap::Args, Clone, Debug)]
pub struct KernelBenchArgs {
    #[arg(long, default_value_t = 1920)]
    pub width: u32,
    #[arg(long, default_value_t = 1080)]
    pub height: u32,
    /// Triangle counts of the generated scenes (comma-separated).
    #[arg(long, value_delimiter = ',', default_value = "100000,1000000,2000000")]
    pub generated: Vec<u64>,
    /// Skip the generated scenes.
    #[arg(long)]
    pub skip_generated: bool,
    /// Skip the bundled scenes (bunny, teapot, cornell).
    #[arg(long)]
    pub skip_bundled: bool,
    /// Timed passes per kernel; the best pass is reported.
    #[arg(long, default_value_t = 2)]
    pub repeats: u32,
    /// Do not run Embree even if it is installed.
    #[arg(long)]
    pub no_embree: bool,
    /// Skip the whole-render table (the monolithic renderer at 1 spp beside Embree).
    #[arg(long)]
    pub skip_whole_render: bool,
    /// Append the tables to this CSV file.
    #[arg(long)]
    pub csv: Option<PathBuf>,
    /// Where generated scenes are cached.
    #[arg(long, default_value = "target/bench-scenes")]
    pub scene_dir: PathBuf,
    /// Where the ray files and the compiled Embree harness go.
    #[arg(long, default_value = "target/kernel-bench")]
    pub work_dir: PathBuf,
}

/// What one scene measured.
struct SceneResult {
    name: String,
    triangles: usize,
    primary: usize,
    primary_s: f64,
    /// Our coherent path: the same rays in packets of
    /// [`CLOSEST_PACKET`](hort_core::bvh::CLOSEST_PACKET) consecutive rays.
    packets_s: f64,
    /// The shadow rays in packets of [`RAY_PACKET`](hort_core::bvh::RAY_PACKET) consecutive
    /// rays ([`Bvh::occluded_many`]).
    shadow_packets_s: f64,
    primary_hits: usize,
    shadow: usize,
    shadow_s: f64,
    occluded: usize,
    /// Best build time on one thread.
    build_s: f64,
    /// Best build time on every core ([`available_cores`]), and how many that is.
    build_all_cores: (f64, usize),
    load: SplitLoad,
    embree: Option<EmbreeResult>,
    /// The whole render at 1 spp, per tree (`whole_render.rs`).
    whole: Vec<super::breakdown::Breakdown>,
    #[cfg(feature = "obvhs-bench")]
    obvhs: super::obvhs_kernel::ObvhsResult,
}

/// What the Embree harness measured on one ray file (seconds are the best of its repeats).
#[derive(serde::Deserialize)]
pub(super) struct EmbreeResult {
    pub build_s: f64,
    /// `rtcIntersect1` over the primary rays.
    pub primary_s: f64,
    /// `rtcIntersect16` over the primary rays, 16 consecutive rays a packet.
    pub primary16_s: f64,
    /// The same with the context's coherent flag, as Mitsuba 3 traces camera rays.
    pub primary16_coherent_s: f64,
    /// Primary rays whose hit triangle is ours.
    pub primary_same_id: u64,
    /// `rtcOccluded1` over the shadow segments.
    pub shadow_s: f64,
    /// Shadow segments whose answer is ours.
    pub shadow_same: u64,
}

/// Rays and our answers to them, as the Embree harness reads them.
#[derive(Clone, Copy)]
pub(super) struct RaySet<'a> {
    pub primary: &'a [Ray],
    pub hits: &'a [Option<hort_core::bvh::ClosestHit>],
    /// Shadow segments: a ray and its far end.
    pub shadow: &'a [(Ray, f32)],
    pub occluded: &'a [bool],
}

/// Writes `rays` to `file`, runs the compiled Embree `harness` on it (`repeats` passes, one
/// thread) and returns what it measured; the file is removed afterwards.
pub(super) fn run_embree(
    harness: &Path,
    file: &Path,
    name: &str,
    scene: &Scene,
    rays: &RaySet<'_>,
    repeats: u32,
) -> Result<EmbreeResult> {
    write_ray_file(file, scene, rays)?;
    let output = Command::new(harness)
        .arg(file)
        .arg(repeats.to_string())
        .output()
        .with_context(|| format!("cannot run {}", harness.display()));
    let _ = std::fs::remove_file(file);
    let output = output?;
    if !output.status.success() {
        bail!(
            "Embree harness failed on {name}: {}",
            String::from_utf8_lossy(&output.stderr)
        );
    }
    serde_json::from_slice(&output.stdout).context("Embree harness output")
}

pub fn run_kernel_bench(args: &KernelBenchArgs) -> Result<()> {
    std::fs::create_dir_all(&args.work_dir)
        .with_context(|| format!("cannot create {}", args.work_dir.display()))?;
    let harness = if args.no_embree {
        eprintln!("Embree: skipped (--no-embree)");
        None
    } else {
        match compile_harness(&args.work_dir) {
            Ok(path) => Some(path),
            Err(e) => {
                eprintln!(
                    "Embree unavailable ({e:#}); reporting our kernel only \
                     (`bash eval/embree.sh` installs it)"
                );
                None
            }
        }
    };
    let mut scenes: Vec<(String, PathBuf)> = Vec::new();
    if !args.skip_bundled {
        for name in ["bunny", "teapot", "cornell"] {
            scenes.push((name.into(), bundled(&format!("{name}/{name}.json"))));
        }
    }
    let generated_counts: &[u64] = if args.skip_generated {
        &[]
    } else {
        &args.generated
    };
    for &n in generated_counts {
        scenes.push((
            format!("generated {}k", n / 1000),
            generated(&args.scene_dir, n, 1)?,
        ));
    }
    let mut results = Vec::new();
    for (name, path) in scenes {
        let scene = load_scene(&path)?;
        let result = bench_scene(&name, &scene, args, harness.as_deref())?;
        eprintln!(
            "{name}: ours {:.2} / {:.2} Mrays/s primary / shadow",
            mrays(result.primary, result.primary_s),
            mrays(result.shadow, result.shadow_s)
        );
        results.push(result);
    }
    let whole: Vec<_> = results.iter_mut().flat_map(|r| r.whole.drain(..)).collect();
    let mut tables = vec![ray_table(&results, args), build_table(&results)];
    if !whole.is_empty() {
        let settings = hort_core::render::RenderSettings {
            width: args.width,
            height: args.height,
            spp: 1,
            threads: 1,
            frame: Default::default(),
        };
        tables.push(super::breakdown::table(&whole, settings));
    }
    for t in &tables {
        t.print();
        if let Some(csv) = &args.csv {
            t.append_csv(csv)?;
        }
    }
    if harness.is_none() {
        println!("\n(Embree unavailable: `bash eval/embree.sh` installs it and a C compiler)");
    }
    #[cfg(not(feature = "obvhs-bench"))]
    println!("\n(obvhs not compiled in: build with --features obvhs-bench for its columns)");
    Ok(())
}

/// Compiles the harness into `dir` with `cc`; errors if there is no compiler or no Embree.
pub(super) fn compile_harness(dir: &Path) -> Result<PathBuf> {
    let source = Path::new(env!("CARGO_MANIFEST_DIR")).join("bench/embree_harness.c");
    let out = dir.join("embree_harness");
    let output = Command::new("cc")
        .arg("-O2")
        .arg(&source)
        .arg("-o")
        .arg(&out)
        .arg("-lembree3")
        .output()
        .context("cannot run cc")?;
    if !output.status.success() {
        bail!(
            "cc -lembree3 failed: {}",
            String::from_utf8_lossy(&output.stderr)
                .lines()
                .next()
                .unwrap_or("")
        );
    }
    Ok(out)
}

fn mrays(rays: usize, seconds: f64) -> f64 {
    rays as f64 / seconds.max(1e-12) / 1e6
}

fn bench_scene(
    name: &str,
    scene: &Scene,
    args: &KernelBenchArgs,
    harness: Option<&Path>,
) -> Result<SceneResult> {
    let n = scene.mesh.triangle_count();
    let triangles: Vec<_> = (0..n).map(|i| scene.mesh.corners(i)).collect();
    // The inputs are copied outside the timed part, as Embree's buffers are filled before
    // its timed commit.
    let build_on = |threads| {
        best_of_prepared(
            args.repeats,
            || (triangles.clone(), (0..n as u32).collect()),
            |(triangles, ids)| Bvh::build_on_threads(triangles, ids, threads),
        )
    };
    let (build_s, bvh) = build_on(1);
    let cores = available_cores();
    let (all_cores_s, on_all_cores) = build_on(cores);
    if on_all_cores != bvh {
        bail!("{name}: the BVH built on {cores} threads differs from the one built on one");
    }
    drop((triangles, on_all_cores));

    let camera = Camera::new(
        &scene.camera_for(args.width, args.height),
        args.width,
        args.height,
    )?;
    // Pixel centres in the renderer's tile order: bands of four rows, 4x4 tiles left to
    // right, so 16 consecutive rays are one tile (Embree x16) and 32 two side by side (ours).
    let width = u64::from(args.width);
    let primary: Vec<Ray> = band_runs(0..width * u64::from(args.height), args.width)
        .flat_map(|band| tile_order(band, args.width))
        .map(|pixel| {
            let (x, y) = (pixel % width, pixel / width);
            camera.ray(x as f64 + 0.5, y as f64 + 0.5)
        })
        .collect();
    // Output buffers are allocated (and faulted in) before timing, as Embree's are.
    let mut hits = vec![None; primary.len()];
    let (primary_s, ()) = best_of(args.repeats, || {
        for (out, r) in hits.iter_mut().zip(&primary) {
            *out = bvh.closest_hit(r);
        }
    });
    let mut packet_hits = vec![None; primary.len()];
    let (packets_s, ()) = best_of(args.repeats, || {
        bvh.closest_hits(&primary, &mut packet_hits);
    });
    if packet_hits != hits {
        bail!("{name}: packets and single rays disagree");
    }
    let light = scene.lights.first();
    let shadow: Vec<(Ray, f32)> = primary
        .iter()
        .zip(&hits)
        .filter_map(|(ray, hit)| {
            let sp = surface_of(&scene.mesh, &bvh, hit.as_ref()?, ray);
            let test = shadow_test(&sp, light?)?;
            Some((test.ray, test.t_max))
        })
        .collect();
    let mut occluded = vec![false; shadow.len()];
    let (shadow_s, ()) = best_of(args.repeats, || {
        for (out, (r, t_max)) in occluded.iter_mut().zip(&shadow) {
            *out = bvh.occluded(r, *t_max);
        }
    });
    let mut packet_occluded = vec![false; shadow.len()];
    let (shadow_packets_s, ()) = best_of(args.repeats, || {
        bvh.occluded_many(&shadow, &mut packet_occluded);
    });
    if packet_occluded != occluded {
        bail!("{name}: shadow packets and single rays disagree");
    }
    let whole = if args.skip_whole_render {
        Vec::new()
    } else {
        let harness = harness.map(|h| (h, args.work_dir.as_path()));
        let size = (args.width, args.height);
        super::whole_render::measure(name, scene, &bvh, size, args.repeats, harness)?
    };
    let load = split_load(scene, bvh.clone(), args.repeats)?;

    let embree = match harness {
        None => None,
        Some(h) => {
            let file = args
                .work_dir
                .join(format!("rays-{}.bin", name.replace(' ', "-")));
            let rays = RaySet {
                primary: &primary,
                hits: &hits,
                shadow: &shadow,
                occluded: &occluded,
            };
            Some(run_embree(h, &file, name, scene, &rays, args.repeats)?)
        }
    };
    Ok(SceneResult {
        name: name.to_string(),
        triangles: bvh.triangle_count(),
        primary: primary.len(),
        primary_s,
        packets_s,
        shadow_packets_s,
        primary_hits: hits.iter().flatten().count(),
        shadow: shadow.len(),
        shadow_s,
        occluded: occluded.iter().filter(|&&o| o).count(),
        build_s,
        build_all_cores: (all_cores_s, cores),
        load,
        embree,
        whole,
        #[cfg(feature = "obvhs-bench")]
        obvhs: super::obvhs_kernel::run(scene, &primary, &hits, &shadow, &occluded, args.repeats),
    })
}

/// Loading the whole scene stored as one split object, against a plain copy of what it loads.
struct SplitLoad {
    /// Best seconds of `decode_split` (decompression, checksums, validation, BVH reassembly):
    /// what a task pays before tracing.
    decode_s: f64,
    /// Best seconds of a plain copy of the decoded object into fresh memory (`clone`: the same
    /// arrays, allocated and written once), the floor any loader pays for its output.
    copy_s: f64,
    /// Stored (compressed block) bytes.
    stored: usize,
    /// Raw (decompressed) bytes the block declares.
    raw: u64,
}

/// Times decoding the whole scene stored as one split object and copying the decoded object,
/// alternately, best of `repeats` each (so both see the same machine load).
fn split_load(scene: &Scene, bvh: Bvh, repeats: u32) -> Result<SplitLoad> {
    let shading = bvh
        .ids()
        .iter()
        .map(|&id| shading_of(&scene.mesh, id))
        .collect();
    let object = SplitObject {
        split: 0,
        bvh,
        shading,
        textures: Default::default(),
    };
    let bytes = encode_split(&object);
    let (mut decode_s, mut copy_s) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..repeats.max(1) {
        let (s, decoded) = best_of(1, || decode_split("bench", &bytes));
        decode_s = decode_s.min(s);
        let decoded = decoded?;
        if decoded != object {
            bail!("split object: decoded object differs from the encoded one");
        }
        let (s, copy) = best_of(1, || decoded.clone());
        copy_s = copy_s.min(s);
        drop(copy);
    }
    let raw = bytes
        .get(20..28)
        .and_then(|b| b.try_into().ok())
        .map_or(0, u64::from_le_bytes);
    Ok(SplitLoad {
        decode_s,
        copy_s,
        stored: bytes.len(),
        raw,
    })
}

/// Writes the ray file `embree_harness.c` documents.
fn write_ray_file(path: &Path, scene: &Scene, rays: &RaySet<'_>) -> Result<()> {
    let RaySet {
        primary,
        hits,
        shadow,
        occluded,
    } = *rays;
    let mut out = Vec::new();
    let f32s = |out: &mut Vec<u8>, v: &[f32]| {
        for x in v {
            out.extend_from_slice(&x.to_le_bytes());
        }
    };
    out.extend_from_slice(b"HORTKRN1");
    let n = scene.mesh.triangle_count();
    for v in [n, primary.len(), shadow.len(), 0] {
        out.extend_from_slice(&(v as u32).to_le_bytes());
    }
    for i in 0..n {
        for c in scene.mesh.corners(i) {
            f32s(&mut out, &c.to_array());
        }
    }
    for r in primary {
        f32s(&mut out, &r.origin.to_array());
        f32s(&mut out, &r.dir.to_array());
    }
    for h in hits {
        let (id, t) = h.map_or((u32::MAX, f32::INFINITY), |h| (h.id, h.t));
        out.extend_from_slice(&id.to_le_bytes());
        out.extend_from_slice(&t.to_le_bytes());
    }
    for (r, t_max) in shadow {
        f32s(&mut out, &r.origin.to_array());
        f32s(&mut out, &r.dir.to_array());
        f32s(&mut out, &[*t_max]);
    }
    out.extend(occluded.iter().map(|&o| u8::from(o)));
    std::fs::File::create(path)
        .and_then(|mut f| f.write_all(&out))
        .with_context(|| format!("cannot write {}", path.display()))
}

fn ray_table(results: &[SceneResult], args: &KernelBenchArgs) -> Table {
    let mut table = Table::new(
        &format!(
            "single-thread kernel vs native Embree 3 on identical rays, {}x{} (Mrays/s; ratio = ours / Embree single rays)",
            args.width, args.height
        ),
        &[
            "scene",
            "triangles",
            "primary rays",
            "hit %",
            "ours primary",
            "Embree primary",
            "ratio",
            "Embree x16",
            "ours packets",
            "ratio x16",
            "Embree x16 coherent",
            "ratio x16 coherent",
            "same id %",
            "shadow rays",
            "occluded %",
            "ours shadow",
            "Embree shadow",
            "ratio",
            "ours shadow packets",
            "same %",
        ],
    );
    #[cfg(feature = "obvhs-bench")]
    table
        .header
        .extend(super::obvhs_kernel::RAY_HEADER.map(String::from));
    let pct = |a: u64, b: usize| format!("{:.2}", 100.0 * a as f64 / b.max(1) as f64);
    for r in results {
        let ours_p = mrays(r.primary, r.primary_s);
        let ours_s = mrays(r.shadow, r.shadow_s);
        let ours_x16 = mrays(r.primary, r.packets_s);
        let ours_s16 = mrays(r.shadow, r.shadow_packets_s);
        let mut row = vec![
            r.name.clone(),
            r.triangles.to_string(),
            r.primary.to_string(),
            pct(r.primary_hits as u64, r.primary),
            format!("{ours_p:.2}"),
        ];
        let dash = || "-".to_string();
        match &r.embree {
            Some(e) => {
                let ep = mrays(r.primary, e.primary_s);
                let es = mrays(r.shadow, e.shadow_s);
                row.extend([
                    format!("{ep:.2}"),
                    f3(ours_p / ep),
                    format!("{:.2}", mrays(r.primary, e.primary16_s)),
                    format!("{ours_x16:.2}"),
                    f3(ours_x16 / mrays(r.primary, e.primary16_s)),
                    format!("{:.2}", mrays(r.primary, e.primary16_coherent_s)),
                    f3(ours_x16 / mrays(r.primary, e.primary16_coherent_s)),
                    pct(e.primary_same_id, r.primary),
                    r.shadow.to_string(),
                    pct(r.occluded as u64, r.shadow),
                    format!("{ours_s:.2}"),
                    format!("{es:.2}"),
                    f3(ours_s / es),
                    format!("{ours_s16:.2}"),
                    pct(e.shadow_same, r.shadow),
                ]);
            }
            None => row.extend([
                dash(),
                dash(),
                dash(),
                format!("{ours_x16:.2}"),
                dash(),
                dash(),
                dash(),
                dash(),
                r.shadow.to_string(),
                pct(r.occluded as u64, r.shadow),
                format!("{ours_s:.2}"),
                dash(),
                dash(),
                format!("{ours_s16:.2}"),
                dash(),
            ]),
        }
        #[cfg(feature = "obvhs-bench")]
        row.extend(super::obvhs_kernel::ray_cells(
            &r.obvhs,
            r.primary,
            r.shadow,
            (r.primary_s, r.shadow_s),
            r.embree.as_ref().map(|e| (e.primary_s, e.shadow_s)),
        ));
        table.push(row);
    }
    table
}

fn build_table(results: &[SceneResult]) -> Table {
    let mut table = Table::new(
        "BVH build (best of the repeats; ratio = ours on one thread / Embree rtcCommitScene on one thread) and split-object load seconds (copy = a clone of the decoded object, same run)",
        &[
            "scene",
            "triangles",
            "ours build s",
            "Embree build s",
            "ratio",
            "ours build s, all cores",
            "split load s",
            "copy s",
            "load / copy",
            "stored MB",
            "raw MB",
        ],
    );
    #[cfg(feature = "obvhs-bench")]
    table
        .header
        .extend(super::obvhs_kernel::BUILD_HEADER.map(String::from));
    for r in results {
        let (eb, ratio) = r.embree.as_ref().map_or(("-".into(), "-".into()), |e| {
            (f3(e.build_s), f3(r.build_s / e.build_s))
        });
        table.push(vec![
            r.name.clone(),
            r.triangles.to_string(),
            f3(r.build_s),
            eb,
            ratio,
            format!(
                "{} ({} threads)",
                f3(r.build_all_cores.0),
                r.build_all_cores.1
            ),
            f3(r.load.decode_s),
            f3(r.load.copy_s),
            f3(r.load.decode_s / r.load.copy_s),
            format!("{:.1}", r.load.stored as f64 / 1e6),
            format!("{:.1}", r.load.raw as f64 / 1e6),
        ]);
        #[cfg(feature = "obvhs-bench")]
        if let Some(row) = table.rows.last_mut() {
            row.extend(super::obvhs_kernel::build_cells(&r.obvhs, r.build_s));
        }
    }
    table
}
