//! Scaled and translated scenes render like the original: every vertex, the camera and the
//! point lights are mapped by p -> s p + T (and point intensities by s^2, so irradiance is the
//! same), written with full double precision, and rendered at the same image size. Scales run
//! from 1e-4 to 1e4, translations up to 1e6 per axis. A pixel differs if its hit names another
//! triangle or an 8-bit sRGB channel moves by more than one level (`support::Difference`);
//! fewer than 0.01% of pixels may differ, and at most 0.02% may move by one level.

use crate::support::{Difference, Scratch, difference, monolithic, scene_path};
use hort_core::render::RenderOutput;
use hort_core::scene::load_scene;
use serde_json::Value;
use std::path::Path;

const W: u32 = 320;
const H: u32 = 240;

/// Writes `p -> s p + t` of a bundled manifest scene (its meshes and material libraries beside
/// it) into `dir`, and returns the new manifest's path.
fn transformed(rel: &str, s: f64, t: [f64; 3], dir: &Path) -> std::path::PathBuf {
    let manifest_path = scene_path(rel);
    let folder = manifest_path.parent().unwrap();
    let map = |v: &Value| -> Value {
        let c: Vec<f64> = v
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        serde_json::json!([s * c[0] + t[0], s * c[1] + t[1], s * c[2] + t[2]])
    };
    let mut m: Value = serde_json::from_str(&std::fs::read_to_string(&manifest_path).unwrap())
        .expect("manifest JSON");
    for field in ["eye", "look_at"] {
        m["camera"][field] = map(&m["camera"][field]);
    }
    for light in m["lights"].as_array_mut().unwrap() {
        if light["kind"] == "point" {
            light["position"] = map(&light["position"]);
            let i = light["intensity"].as_f64().unwrap();
            light["intensity"] = serde_json::json!(i * s * s);
        }
    }
    for entry in std::fs::read_dir(folder).unwrap() {
        let path = entry.unwrap().path();
        let name = path.file_name().unwrap();
        match path.extension().and_then(|e| e.to_str()) {
            Some("obj") => {
                let text = std::fs::read_to_string(&path).unwrap();
                let moved: String = text
                    .lines()
                    .map(|line| match line.strip_prefix("v ") {
                        Some(rest) => {
                            let c: Vec<f64> = rest
                                .split_whitespace()
                                .map(|w| w.parse().unwrap())
                                .collect();
                            // `{}` of an f64 is its shortest round-trip decimal: no detail lost.
                            format!(
                                "v {} {} {}\n",
                                s * c[0] + t[0],
                                s * c[1] + t[1],
                                s * c[2] + t[2]
                            )
                        }
                        None => format!("{line}\n"),
                    })
                    .collect();
                std::fs::write(dir.join(name), moved).unwrap();
            }
            Some("mtl") => {
                std::fs::copy(&path, dir.join(name)).unwrap();
            }
            _ => {}
        }
    }
    let out = dir.join(manifest_path.file_name().unwrap());
    std::fs::write(&out, serde_json::to_string(&m).unwrap()).unwrap();
    out
}

fn render_transformed(rel: &str, s: f64, t: [f64; 3]) -> RenderOutput {
    let scratch = Scratch::new("transformed");
    let path = transformed(rel, s, t, scratch.path());
    let scene = load_scene(&path).unwrap_or_else(|e| panic!("{rel} x{s} +{t:?}: {e}"));
    monolithic(&scene, W, H)
}

/// Every scale and translation against the original, for one scene; returns the worst case.
fn check(rel: &str) -> Difference {
    let original = render_transformed(rel, 1.0, [0.0; 3]);
    let hits = original.hits.iter().filter(|h| !h.is_miss()).count();
    assert!(
        hits > (W * H / 4) as usize,
        "{rel}: the scene must fill the view"
    );
    let mut worst = Difference::default();
    let limit = (W * H) as usize / 10_000; // 0.01% of the pixels, rounded down
    for s in [1e-4, 1e-2, 1.0, 1e2, 1e4] {
        for t in [
            [0.0; 3],
            [1e3, -2e3, 5e2],
            [1e6, 1e6, -1e6],
            [-1e6, 3e5, 1e6],
        ] {
            let d = difference(&original, &render_transformed(rel, s, t));
            println!(
                "{rel} scale {s:e} translation {t:?}: {} pixels differ ({} hits; {} more by one \
                 sRGB level; at most {} levels), max relative radiance difference {:e}",
                d.pixels, d.hits, d.srgb8_one_level, d.max_srgb8, d.max_relative
            );
            assert!(
                d.pixels <= limit,
                "{rel} x{s} +{t:?}: {} of {} pixels differ",
                d.pixels,
                W * H
            );
            assert!(
                d.srgb8_one_level <= 2 * limit,
                "{rel} x{s} +{t:?}: {} of {} pixels move by one sRGB level",
                d.srgb8_one_level,
                W * H
            );
            if (d.pixels, d.srgb8_one_level) >= (worst.pixels, worst.srgb8_one_level) {
                worst = d;
            }
        }
    }
    worst
}

#[test]
fn scaled_and_translated_bunny_renders_like_the_original() {
    let worst = check("bunny/bunny.json");
    println!(
        "bunny: worst case {} of {} pixels differ, {} by one level",
        worst.pixels,
        W * H,
        worst.srgb8_one_level
    );
}

#[test]
fn scaled_and_translated_cornell_box_renders_like_the_original() {
    let worst = check("cornell/cornell.json");
    println!(
        "cornell: worst case {} of {} pixels differ, {} by one level",
        worst.pixels,
        W * H,
        worst.srgb8_one_level
    );
}
