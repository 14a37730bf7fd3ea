//! `hort render` on scenes as new users bring them: a bare OBJ in a portrait image, manifests
//! without light, MTL features that are not rendered, OBJ files from the wild.

use crate::common;

use common::{hort, scene, scratch};
use hort_core::hits::{Hit, decode_hits};
use std::path::{Path, PathBuf};
use std::process::Output;

fn write(dir: &Path, name: &str, text: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Renders `scene_file` at `width` x `height` with the given mode flags; returns the PFM bytes,
/// the hit-buffer bytes and standard error.
fn render(
    scene_file: &Path,
    dir: &Path,
    width: u32,
    height: u32,
    mode: &[&str],
) -> (Vec<u8>, Vec<u8>, String) {
    let (out, hits) = (dir.join("o.pfm"), dir.join("h.bin"));
    let (w, h) = (width.to_string(), height.to_string());
    let mut args = vec![
        "render",
        scene_file.to_str().unwrap(),
        "--width",
        &w,
        "--height",
        &h,
        "--out",
        out.to_str().unwrap(),
        "--hits",
        hits.to_str().unwrap(),
    ];
    args.extend_from_slice(mode);
    let o = hort(&args);
    assert!(o.status.success(), "{}", stderr(&o));
    (
        std::fs::read(out).unwrap(),
        std::fs::read(hits).unwrap(),
        stderr(&o),
    )
}

/// The warning lines of a run's standard error, without the `warning: ` prefix.
fn warnings(err: &str) -> Vec<&str> {
    err.lines()
        .filter_map(|l| l.strip_prefix("warning: "))
        .collect()
}

/// Hits on the first or last row or column of a `width` x `height` hit buffer, and all hits.
fn border_and_all_hits(hits: &[Hit], width: u32, height: u32) -> (usize, usize) {
    let on_border = |i: usize| {
        let (x, y) = (i as u32 % width, i as u32 / width);
        x == 0 || y == 0 || x == width - 1 || y == height - 1
    };
    let hit = |i: &usize| !hits[*i].is_miss();
    let border = (0..hits.len())
        .filter(|&i| on_border(i))
        .filter(hit)
        .count();
    (border, (0..hits.len()).filter(hit).count())
}

// 64-bit FNV-1a, as core/tests/golden.rs pins the renders.
use hort_core::digest::fnv1a64;

/// Column 0 of a 1 x 48 image and column 47 of a 95 x 48 image look through the same image
/// centre line, so with the same camera their hits are equal bit for bit.
fn centre_lines(scene_file: &Path, dir: &Path) -> (Vec<Hit>, Vec<Hit>) {
    let (_, thin, _) = render(scene_file, dir, 1, 48, &["--monolithic"]);
    let (_, wide, _) = render(scene_file, dir, 95, 48, &["--monolithic"]);
    let wide = decode_hits(&wide, 95, 48).unwrap();
    let wide = (0..48).map(|y| wide[y * 95 + 47]).collect();
    (decode_hits(&thin, 1, 48).unwrap(), wide)
}

/// The user's command: `hort render bunny.obj --width 300 --height 800` cut off the bunny's head
/// and tail. The whole bunny must be in the picture: no hit on the image border, in the
/// monolithic renderer, the in-process pipeline and the emulator (whose plan carries the camera
/// to the tasks).
#[test]
fn a_portrait_image_of_a_bare_obj_shows_the_whole_model() {
    let dir = scratch("portrait");
    let bunny = scene("bunny/bunny.obj");
    let (_, hits, _) = render(&bunny, &dir, 300, 800, &["--monolithic"]);
    let hits = decode_hits(&hits, 300, 800).unwrap();
    let (border, all) = border_and_all_hits(&hits, 300, 800);
    assert!(
        all > 10_000,
        "the bunny fills a good part of the picture ({all} hits)"
    );
    assert_eq!(border, 0, "the bunny touches the image border");
    // The pipeline frames it the same way, bit for bit.
    let (mono_pfm, mono_hits, _) = render(&bunny, &dir, 60, 160, &["--monolithic"]);
    let (pipe_pfm, pipe_hits, _) = render(&bunny, &dir, 60, 160, &["--in-process"]);
    assert!(mono_pfm == pipe_pfm && mono_hits == pipe_hits);
    let (emu_pfm, emu_hits, _) = render(&bunny, &dir, 60, 160, &["--workers", "2"]);
    assert!(mono_pfm == emu_pfm && mono_hits == emu_hits);
    let hits = decode_hits(&pipe_hits, 60, 160).unwrap();
    assert_eq!(border_and_all_hits(&hits, 60, 160).0, 0);
    // The camera moved back for the portrait image: it sees the centre line differently.
    let (thin, wide) = centre_lines(&bunny, &dir);
    assert_ne!(thin, wide);
}

/// Landscape images of a bare OBJ are what they were: the digests core/tests/golden.rs pins
/// for bunny.obj at 64x48, from the command line in both render modes.
#[test]
fn a_landscape_image_of_a_bare_obj_is_unchanged() {
    let dir = scratch("landscape");
    for mode in ["--monolithic", "--in-process"] {
        let (pfm, hits, _) = render(&scene("bunny/bunny.obj"), &dir, 64, 48, &[mode]);
        assert_eq!(fnv1a64(&pfm), 0x3365_c19d_bbbd_e214, "{mode}");
        assert_eq!(fnv1a64(&hits), 0xdbcb_80a5_ae54_17e0, "{mode}");
    }
}

/// A manifest camera is the user's choice, at any aspect ratio: an extreme portrait image sees
/// along its centre line exactly what a landscape image does.
#[test]
fn a_manifest_camera_is_not_reframed() {
    let dir = scratch("manifest-camera");
    let (thin, wide) = centre_lines(&scene("bunny/bunny.json"), &dir);
    assert!(thin.iter().any(|h| !h.is_miss()));
    assert_eq!(thin, wide);
}

/// A manifest that lights nothing renders (black) but says so, once, with what to do.
#[test]
fn a_manifest_without_light_warns_that_the_image_will_be_black() {
    let dir = scratch("no-light");
    let obj = std::fs::read(scene("bunny/bunny.obj")).unwrap();
    write(&dir, "bunny.obj", &obj);
    let manifest = write(
        &dir,
        "dark.json",
        br#"{"meshes": ["bunny.obj"], "lights": []}"#,
    );
    let (pfm, _, err) = render(&manifest, &dir, 32, 24, &["--monolithic"]);
    let w = warnings(&err);
    assert_eq!(w.len(), 1, "{err}");
    assert_eq!(
        w[0],
        format!(
            "{}: manifest field `lights` is an empty list and `ambient` is 0, so nothing is lit \
             and the image will be black (only the background shows); leave `lights` out to get \
             the default light, or add one, e.g. \"lights\": [{{\"kind\": \"point\", \
             \"position\": [x, y, z], \"intensity\": 100}}]",
            manifest.display()
        )
    );
    let header = b"PF\n32 24\n-1.0\n".len();
    assert!(pfm[header..].iter().all(|&b| b == 0), "the image is black");
}

/// An exported OBJ with a texture that did not come with it, a shiny bright material, skin
/// weights and normals it never defines: rendered with `--missing-textures flat`, with one
/// warning per thing that is not drawn as the file asks.
#[test]
fn an_obj_from_the_wild_renders_with_warnings() {
    let dir = scratch("wild");
    write(
        &dir,
        "wild.mtl",
        b"newmtl body\nKd 0.8 0.7 0.6\nmap_Kd body.png\nnewmtl eyes\nKd 1.5 1.5 1.5\nKs 1 1 1\n",
    );
    let obj = write(
        &dir,
        "wild.obj",
        b"mtllib wild.mtl\nv 0 0 0\nvw 1 0 1\nv 1 0 0\nvw 2 0 1\nv 0 1 0\nvw 3 0 1\nv 1 1 0.5\n\
          usemtl body\nf 1//1 2//1 3//1\nusemtl eyes\nf 2//1 4//1 3//1\n",
    );
    let (_, hits, err) = render(
        &obj,
        &dir,
        32,
        24,
        &["--monolithic", "--missing-textures", "flat"],
    );
    let hits = decode_hits(&hits, 32, 24).unwrap();
    assert!(hits.iter().any(|h| !h.is_miss()));
    let (o, m) = (obj.display(), dir.join("wild.mtl"));
    let m = m.display();
    assert_eq!(
        warnings(&err),
        vec![
            format!(
                "{m}:6: material \"eyes\" has a specular colour (Ks 1 1 1); highlights and \
                 reflections are not rendered, the surface is purely diffuse (Kd only)"
            ),
            format!(
                "{m}:5: material \"eyes\" has a diffuse colour above 1 (Kd 1.5 1.5 1.5); a surface \
                 that reflects more light than it receives is not physically plausible; it is \
                 rendered as given (use Kd values from 0 to 1)"
            ),
            format!(
                "{}: texture of {m}:3 material \"body\": the file does not exist; the surface \
                 shows its flat Kd colour instead (--missing-textures flat)",
                dir.join("body.png").display()
            ),
            format!("{o}:3: unknown statement \"vw\" skipped"),
            format!(
                "{o}:10: faces name vertex normals, but the file defines none (no \"vn\" \
                 statements); those faces use their geometric normal (flat shading)"
            ),
        ],
        "{err}"
    );
}

/// Not every file is an OBJ: binary data and other text formats still fail with status 1 and
/// one message naming the file and line.
#[test]
fn files_that_are_not_obj_are_refused() {
    let dir = scratch("not-obj");
    let cases: [(&str, &[u8], &str); 3] = [
        (
            "png.obj",
            b"\x89PNG\r\n\x1a\n\0\0\0\rIHDR",
            "1: not an OBJ file: binary data",
        ),
        (
            "page.obj",
            b"<!DOCTYPE html>\n<html></html>\n",
            "1: not an OBJ file: unknown statement \"<!DOCTYPE\"",
        ),
        (
            "normals.obj",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//2 3//1\n",
            "5: face refers to normal 2, but only 1 normal is defined so far",
        ),
    ];
    for (name, bytes, tail) in cases {
        let p = write(&dir, name, bytes);
        let out = dir.join("o.png");
        let o = hort(&[
            "render",
            p.to_str().unwrap(),
            "--monolithic",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(1), "{name}: {}", stderr(&o));
        let expected = format!("error: {}:{tail}", p.display());
        assert!(
            stderr(&o).lines().any(|l| l == expected),
            "{name}: expected {expected:?} in\n{}",
            stderr(&o)
        );
    }
}
