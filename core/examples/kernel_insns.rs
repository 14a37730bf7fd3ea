//! Deterministic workload for counting the instructions of the BVH kernel per ray, on x86-64
//! (callgrind) and aarch64 (a qemu-user plugin); driven by
//! `local-emulator/bench/instruction-counts.sh`.
//!
//! `kernel_insns <scene.json> <mode> [WIDTHxHEIGHT]` (default 320x180). The rays are those of
//! `hort bench kernel`: one primary ray per pixel centre traced with [`Bvh::closest_hit`], and
//! for every primary hit the shadow ray towards the scene's first light ([`shadow_test`]),
//! traced with [`Bvh::occluded`]. Each mode runs the previous one plus one step:
//!
//! - `setup`: load the scene, build the BVH, make the primary rays, allocate their results;
//! - `primary`: + trace the primary rays;
//! - `shadow-rays`: + make the shadow rays from the hits, allocate their results;
//! - `shadow`: + trace the shadow rays;
//! - `digest`: all of the above, then FNV-1a digests of the answers (not for counting); fails
//!   unless the ray packets give the single-ray answers;
//! - `packets` (outside the chain): `setup` + the primary rays in ray packets
//!   ([`Bvh::closest_hits`]), so per primary ray in packets = (count(packets) - count(setup)) /
//!   primary rays.
//!
//! So instructions per primary ray = (count(primary) - count(setup)) / primary rays, and per
//! shadow ray = (count(shadow) - count(shadow-rays)) / shadow rays. The counting modes print
//! the same line shape and compute nothing else, so everything but the traced rays cancels.

use hort_core::bvh::{Bvh, ClosestHit};
use hort_core::camera::Camera;
use hort_core::digest::Fnv1a64;
use hort_core::render::{build_scene_bvh, surface_of};
use hort_core::scene::load_scene;
use hort_core::shading::shadow_test;
use hort_core::triangle::Ray;
use std::error::Error;
use std::hint::black_box;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Debug)]
enum Mode {
    Setup,
    Primary,
    ShadowRays,
    Shadow,
    Digest,
    /// Setup, then the primary rays in ray packets (`Bvh::closest_hits`); not part of the
    /// chain above.
    Packets,
}

impl Mode {
    fn parse(s: &str) -> Option<Mode> {
        Some(match s {
            "setup" => Mode::Setup,
            "primary" => Mode::Primary,
            "shadow-rays" => Mode::ShadowRays,
            "shadow" => Mode::Shadow,
            "digest" => Mode::Digest,
            "packets" => Mode::Packets,
            _ => return None,
        })
    }
}

const USAGE: &str = "usage: kernel_insns <scene.json> <setup|primary|shadow-rays|shadow|digest|packets> [WIDTHxHEIGHT]";

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("kernel_insns: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run() -> Result<(), Box<dyn Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.len() < 2 || args.len() > 3 {
        return Err(USAGE.into());
    }
    let path = PathBuf::from(&args[0]);
    let mode = Mode::parse(&args[1]).ok_or(USAGE)?;
    let (width, height) = match args.get(2) {
        None => (320, 180),
        Some(s) => {
            let (w, h) = s.split_once('x').ok_or(USAGE)?;
            (w.parse::<u32>()?, h.parse::<u32>()?)
        }
    };

    let scene = load_scene(&path)?;
    let bvh = build_scene_bvh(&scene.mesh);
    let camera = Camera::new(&scene.camera_for(width, height), width, height)?;
    let primary: Vec<Ray> = (0..height)
        .flat_map(|y| (0..width).map(move |x| camera.ray(f64::from(x) + 0.5, f64::from(y) + 0.5)))
        .collect();
    let mut hits: Vec<Option<ClosestHit>> = vec![None; primary.len()];
    if mode == Mode::Packets {
        trace_packets(&bvh, &primary, &mut hits);
        black_box(&hits);
        println!(
            "mode=packets width={width} height={height} triangles={} primary_rays={}",
            bvh.triangle_count(),
            primary.len()
        );
        return Ok(());
    }
    if mode >= Mode::Primary {
        trace_primary(&bvh, &primary, &mut hits);
    }
    let mut shadow: Vec<(Ray, f32)> = Vec::new();
    let mut occluded: Vec<bool> = Vec::new();
    if mode >= Mode::ShadowRays {
        let light = scene.lights.first().ok_or("the scene has no light")?;
        shadow = primary
            .iter()
            .zip(&hits)
            .filter_map(|(ray, hit)| {
                let sp = surface_of(&scene.mesh, hit.as_ref()?, ray);
                let test = shadow_test(&sp, light)?;
                Some((test.ray, test.t_max))
            })
            .collect();
        occluded = vec![false; shadow.len()];
    }
    if mode >= Mode::Shadow {
        trace_shadow(&bvh, &shadow, &mut occluded);
    }
    black_box((&hits, &occluded));

    println!(
        "mode={} width={width} height={height} triangles={} primary_rays={} shadow_rays={}",
        args[1],
        bvh.triangle_count(),
        primary.len(),
        shadow.len()
    );
    if mode == Mode::Digest {
        let mut packet_hits = vec![None; primary.len()];
        trace_packets(&bvh, &primary, &mut packet_hits);
        if packet_hits != hits {
            return Err("ray packets and single rays disagree".into());
        }
        let mut primary_digest = Fnv1a64::new();
        for hit in &hits {
            match hit {
                None => primary_digest.write(&[0]),
                Some(h) => {
                    primary_digest.write(&[1]);
                    primary_digest.write(&h.id.to_le_bytes());
                    primary_digest.write(&h.t.to_bits().to_le_bytes());
                    for b in h.b {
                        primary_digest.write(&b.to_bits().to_le_bytes());
                    }
                    primary_digest.write(&h.index.to_le_bytes());
                }
            }
        }
        let mut shadow_digest = Fnv1a64::new();
        for (&o, (ray, t_max)) in occluded.iter().zip(&shadow) {
            shadow_digest.write(&[u8::from(o)]);
            for v in ray.origin.to_array().into_iter().chain(ray.dir.to_array()) {
                shadow_digest.write(&v.to_bits().to_le_bytes());
            }
            shadow_digest.write(&t_max.to_bits().to_le_bytes());
        }
        println!(
            "hits={} occluded={} primary_digest={:016x} shadow_digest={:016x}",
            hits.iter().flatten().count(),
            occluded.iter().filter(|&&o| o).count(),
            primary_digest.finish(),
            shadow_digest.finish()
        );
    }
    Ok(())
}

#[inline(never)]
fn trace_packets(bvh: &Bvh, rays: &[Ray], hits: &mut [Option<ClosestHit>]) {
    bvh.closest_hits(rays, hits);
}

#[inline(never)]
fn trace_primary(bvh: &Bvh, rays: &[Ray], hits: &mut [Option<ClosestHit>]) {
    for (out, r) in hits.iter_mut().zip(rays) {
        *out = bvh.closest_hit(r);
    }
}

#[inline(never)]
fn trace_shadow(bvh: &Bvh, rays: &[(Ray, f32)], occluded: &mut [bool]) {
    for (out, (r, t_max)) in occluded.iter_mut().zip(rays) {
        *out = bvh.occluded(r, *t_max);
    }
}
