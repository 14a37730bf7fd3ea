//! Scenes as new users bring them: portrait images of a bare OBJ, manifests without light, MTL
//! features the renderer does not draw, OBJ files with statements or references we do not use.

use super::*;
use crate::render::{RenderSettings, build_scene_bvh, render};

/// A fresh scratch folder per call, removed when dropped.
fn scratch() -> crate::scratch::Scratch {
    crate::scratch::Scratch::new("hort-scene-wild-")
}

fn write(dir: &Path, name: &str, text: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

/// Loads `text` as `x.obj` in a fresh folder, with `files` beside it.
fn load(text: &str, files: &[(&str, &str)]) -> (Result<Scene, String>, PathBuf) {
    let dir = scratch();
    for (name, body) in files {
        write(&dir, name, body.as_bytes());
    }
    let p = write(&dir, "x.obj", text.as_bytes());
    (load_scene(&p).map_err(|e| e.to_string()), p)
}

fn bundled(rel: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenes")
        .join(rel)
}

const TRIANGLE: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

// ---- Framing -------------------------------------------------------------------------------

/// Where `p` lands in a `width` x `height` image seen through `spec`, in [-1, 1] across the
/// image (x to the right, y up), by the camera contract of docs/ARCHITECTURE.md.
fn project(spec: &CameraSpec, width: u32, height: u32, p: DVec3) -> (f64, f64) {
    let f = (spec.look_at - spec.eye).normalize();
    let r = f.cross(spec.up).normalize();
    let u = r.cross(f);
    let tan = (spec.vfov_degrees.to_radians() / 2.0).tan();
    let d = p - spec.eye;
    let depth = d.dot(f);
    assert!(depth > 0.0, "{p} is behind the camera");
    let aspect = f64::from(width) / f64::from(height);
    (d.dot(r) / depth / (tan * aspect), d.dot(u) / depth / tan)
}

fn corners(lo: DVec3, hi: DVec3) -> impl Iterator<Item = DVec3> {
    (0..8).map(move |i| {
        DVec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        )
    })
}

/// The largest |x| or |y| of the projected box corners: at most 1 when all are in the image.
fn extent(spec: &CameraSpec, width: u32, height: u32, lo: DVec3, hi: DVec3) -> f64 {
    corners(lo, hi)
        .map(|p| {
            let (x, y) = project(spec, width, height, p);
            x.abs().max(y.abs())
        })
        .fold(0.0, f64::max)
}

/// The bug a user hit: `hort render bunny.obj --width 300 --height 800` cut off the head and
/// the tail. Every corner of the bounding box must project inside portrait images, and the
/// bounding sphere must fit both fields of view.
#[test]
fn portrait_images_of_a_bare_obj_show_the_whole_bounding_box() {
    let s = load_scene(&bundled("bunny/bunny.obj")).unwrap();
    let (lo, hi) = scene_bounds(&s.mesh, &s.source).unwrap();
    assert!(
        extent(&s.camera, 300, 800, lo, hi) > 1.1,
        "the landscape camera cuts the bunny off at 300x800 (else this test shows nothing)"
    );
    for (w, h) in [(300, 800), (1, 1000), (100, 101), (539, 540), (540, 960)] {
        let spec = s.camera_for(w, h);
        let e = extent(&spec, w, h, lo, hi);
        assert!(e <= 1.0, "{w}x{h}: a box corner projects to {e}");
        // The sphere of radius D/2 around c fits both fields of view.
        let c = (lo + hi) / 2.0;
        let radius = (hi - lo).length() / 2.0;
        let distance = (spec.eye - c).length();
        let tan_v = (22.5f64).to_radians().tan();
        let tan_h = tan_v * f64::from(w) / f64::from(h);
        for tan in [tan_v, tan_h] {
            let sin = tan / (1.0 + tan * tan).sqrt();
            assert!(distance * sin >= radius * (1.0 - 1e-12), "{w}x{h}");
        }
        // Same direction from c as the documented eye, only farther.
        let dir = (spec.eye - c).normalize();
        assert!((dir - DVec3::new(0.0, 0.5, 1.25).normalize()).length() < 1e-12);
        assert_eq!(
            (spec.look_at, spec.up, spec.vfov_degrees),
            (c, DVec3::Y, 45.0)
        );
    }
    // Nearly square portrait images fit already: the camera stays where it is.
    assert_eq!(s.camera_for(539, 540), s.camera);
}

/// The renderer agrees: with the portrait camera no border pixel of the image sees the bunny;
/// with the landscape camera some do.
#[test]
fn portrait_render_keeps_the_bunny_off_the_border() {
    let (w, h) = (30u32, 80u32);
    let mut s = load_scene(&bundled("bunny/bunny.obj")).unwrap();
    let portrait = s.camera_for(w, h);
    // From here on the renderer takes the cameras as given, like manifest cameras.
    s.framed_bounds = None;
    let bvh = build_scene_bvh(&s.mesh);
    let border_hits = |s: &Scene| {
        let settings = RenderSettings {
            width: w,
            height: h,
            spp: 1,
            threads: 1,
            frame: Default::default(),
        };
        let out = render(s, &bvh, settings).unwrap();
        let on_border = |i: usize| {
            let (x, y) = (i as u32 % w, i as u32 / w);
            x == 0 || y == 0 || x == w - 1 || y == h - 1
        };
        let all = out.hits.iter().filter(|hit| !hit.is_miss()).count();
        let border = (0..out.hits.len())
            .filter(|&i| on_border(i) && !out.hits[i].is_miss())
            .count();
        (all, border)
    };
    let (all, border) = border_hits(&s);
    assert!(
        all > 0 && border > 0,
        "landscape camera: {all} hits, {border} on the border"
    );
    s.camera = portrait;
    let (all, border) = border_hits(&s);
    assert!(
        all > 100 && border == 0,
        "portrait camera: {all} hits, {border} on the border"
    );
}

/// Landscape and square images keep today's camera exactly (the golden digests depend on it).
#[test]
fn landscape_framing_is_unchanged() {
    for rel in ["bunny/bunny.obj", "teapot/teapot.obj"] {
        let s = load_scene(&bundled(rel)).unwrap();
        let (lo, hi) = scene_bounds(&s.mesh, &s.source).unwrap();
        assert_eq!(s.camera, default_camera(lo, hi));
        for (w, h) in [(64, 48), (960, 540), (800, 800), (65536, 1), (2, 1)] {
            assert_eq!(s.camera_for(w, h), s.camera, "{rel} {w}x{h}");
            assert_eq!(framed_camera(lo, hi, w, h), default_camera(lo, hi));
        }
    }
}

/// A manifest camera is used as given at any aspect ratio; a manifest without one is framed.
#[test]
fn manifest_cameras_are_untouched() {
    let s = load_scene(&bundled("bunny/bunny.json")).unwrap();
    assert_eq!(s.framed_bounds, None);
    assert_eq!(s.camera_for(300, 800), s.camera);
    let dir = scratch();
    write(&dir, "t.obj", TRIANGLE.as_bytes());
    let p = write(&dir, "s.json", br#"{"meshes": ["t.obj"]}"#);
    let s = load_scene(&p).unwrap();
    assert!(s.framed_bounds.is_some());
    assert_eq!(s.camera_for(64, 48), s.camera);
    assert_ne!(s.camera_for(48, 64), s.camera);
    // A camera replaced after loading is not the automatic one any more.
    let mut s = s;
    s.camera.eye.x += 1.0;
    assert_eq!(s.camera_for(48, 64), s.camera);
}

// ---- Warnings ------------------------------------------------------------------------------

fn manifest_warnings(json: &str, files: &[(&str, &str)]) -> (Vec<String>, PathBuf) {
    let dir = scratch();
    write(&dir, "t.obj", TRIANGLE.as_bytes());
    for (name, body) in files {
        write(&dir, name, body.as_bytes());
    }
    let p = write(&dir, "s.json", json.as_bytes());
    (load_scene(&p).unwrap().warnings, p)
}

#[test]
fn a_manifest_without_light_says_the_image_will_be_black() {
    let (w, p) = manifest_warnings(r#"{"meshes": ["t.obj"], "lights": []}"#, &[]);
    assert_eq!(
        w,
        vec![format!(
            "{}: manifest field `lights` is an empty list and `ambient` is 0, so nothing is lit \
             and the image will be black (only the background shows); leave `lights` out to get \
             the default light, or add one, e.g. \"lights\": [{{\"kind\": \"point\", \
             \"position\": [x, y, z], \"intensity\": 100}}]",
            p.display()
        )]
    );
    let (w, _) = manifest_warnings(
        r#"{"meshes": ["t.obj"], "lights": [{"kind": "point", "position": [0, 1, 1], "intensity": 0}]}"#,
        &[],
    );
    assert_eq!(w.len(), 1);
    assert!(
        w[0].contains("every light in manifest field `lights` has zero intensity or irradiance")
    );
    assert!(w[0].contains("the image will be black"));
    // Ambient light alone is a choice, and lights or the default light are fine.
    for json in [
        r#"{"meshes": ["t.obj"], "lights": [], "ambient": 0.5}"#,
        r#"{"meshes": ["t.obj"]}"#,
        r#"{"meshes": ["t.obj"], "lights": [{"kind": "directional", "direction": [0, -1, 0], "irradiance": 1}]}"#,
    ] {
        assert_eq!(
            manifest_warnings(json, &[]).0,
            Vec::<String>::new(),
            "{json}"
        );
    }
}

#[test]
fn manifest_colours_above_one_are_named() {
    let (w, p) = manifest_warnings(
        r#"{"meshes": ["t.obj"], "materials": {"default": {"kd": [1.5, 0.5, 0.5]}}}"#,
        &[],
    );
    assert_eq!(
        w,
        vec![format!(
            "{}: manifest field `materials.default.kd` is [1.5, 0.5, 0.5]: a diffuse colour \
             above 1 reflects more light than it receives, which is not physically plausible; it \
             is rendered as given (use values from 0 to 1)",
            p.display()
        )]
    );
}

/// Textures, highlights, emission, transparency and Kd above 1: one warning per kind and file,
/// naming the first material and line and counting the others; nothing for harmless values.
#[test]
fn unrendered_mtl_features_warn_once_per_kind() {
    let mtl = "# exported\n\
               newmtl skin\n\
               Ka 1 1 1\n\
               Kd 0.8 0.6 0.5\n\
               Ks 0 0 0\n\
               Ke 0 0 0\n\
               Ns 10\n\
               d 1\n\
               Tr 0\n\
               illum 2\n\
               map_Ks skin.png\n\
               newmtl glass\n\
               Kd 1.2 1.2 1.3\n\
               Ks 0.5 0.5 0.5\n\
               d 0.25\n\
               map_Bump glass_n.png\n\
               newmtl lamp\n\
               Kd 2 2 2\n\
               Ke 10 10 8\n\
               Tr 0.5\n\
               Ks 1 1 1\n\
               newmtl plain\n\
               Kd 0.5 0.5 0.5\n";
    let obj = format!(
        "mtllib m.mtl\nmtllib m.mtl\n{TRIANGLE}usemtl skin\nf 1 2 3\nusemtl glass\nf 1 2 3\n"
    );
    let (s, p) = load(&obj, &[("m.mtl", mtl)]);
    let s = s.unwrap();
    let m = p.parent().unwrap().join("m.mtl");
    let m = m.display();
    assert_eq!(
        s.warnings,
        vec![
            format!(
                "{m}:11: material \"skin\" uses a texture (map_Ks skin.png) (and 1 more \
                 material); only diffuse textures (map_Kd) are rendered; this map is ignored \
                 (the surface shows its Kd colour and map_Kd, if any)"
            ),
            format!(
                "{m}:14: material \"glass\" has a specular colour (Ks 0.5 0.5 0.5) (and 1 more \
                 material); highlights and reflections are not rendered, the surface is purely \
                 diffuse (Kd only)"
            ),
            format!(
                "{m}:19: material \"lamp\" is emissive (Ke 10 10 8); emission is not rendered, \
                 the surface neither glows nor lights the scene (give the scene lights in a \
                 manifest instead)"
            ),
            format!(
                "{m}:15: material \"glass\" is partly transparent (d 0.25) (and 1 more \
                 material); transparency is not rendered, the surface is opaque"
            ),
            format!(
                "{m}:13: material \"glass\" has a diffuse colour above 1 (Kd 1.2 1.2 1.3) (and 1 \
                 more material); a surface that reflects more light than it receives is not \
                 physically plausible; it is rendered as given (use Kd values from 0 to 1)"
            ),
        ]
    );
    // Kd is still used as written.
    let kd: Vec<[f32; 3]> = s.mesh.materials.iter().map(|m| m.kd).collect();
    assert_eq!(kd, vec![[0.7; 3], [0.8, 0.6, 0.5], [1.2, 1.2, 1.3]]);
}

/// Two meshes of one manifest sharing a library: each warning once.
#[test]
fn a_shared_library_warns_once_per_scene() {
    let dir = scratch();
    write(&dir, "m.mtl", b"newmtl a\nKd 0.5 0.5 0.5\nmap_Bump a.png\n");
    let obj = format!("mtllib m.mtl\n{TRIANGLE}usemtl a\nf 1 2 3\n");
    write(&dir, "a.obj", obj.as_bytes());
    write(&dir, "b.obj", obj.as_bytes());
    let p = write(&dir, "s.json", br#"{"meshes": ["a.obj", "b.obj"]}"#);
    let w = load_scene(&p).unwrap().warnings;
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(w[0].contains("m.mtl:3: material \"a\" uses a texture (map_Bump a.png);"));
}

// ---- OBJ files from the wild ---------------------------------------------------------------

/// `f v//vn` and `f v/vt/vn` in a file without any `vn` (nor `vt`): one warning each, naming the
/// first such face, and flat shading.
#[test]
fn faces_naming_normals_of_a_file_without_normals_are_flat() {
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n\
               f 1//1 2//2 3//3\nf 2//1 4//2 3//3\nf 4/1/1 3/2/2 2/3/3\n";
    let (s, p) = load(obj, &[]);
    let s = s.unwrap();
    assert_eq!(s.mesh.triangle_count(), 3);
    assert!(s.mesh.normals.is_empty());
    assert!(s.mesh.triangle_normals.iter().all(|n| *n == [NO_NORMAL; 3]));
    assert_eq!(
        s.warnings,
        vec![
            format!(
                "{}:5: faces name vertex normals, but the file defines none (no \"vn\" \
                 statements); those faces use their geometric normal (flat shading)",
                p.display()
            ),
            format!(
                "{}:7: faces name texture coordinates, but the file defines none (no \"vt\" \
                 statements); they are ignored (their materials show no texture)",
                p.display()
            ),
        ]
    );
    // With texture coordinates defined, `f v/vt/vn` only warns about the normals.
    let (s, _) = load(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1/1 2/1/1 3/1/1\n",
        &[],
    );
    let w = s.unwrap().warnings;
    assert_eq!(w.len(), 1);
    assert!(w[0].contains(":5: faces name vertex normals"), "{w:?}");
}

/// What stays refused: normal or texture indices beyond an existing nonzero count, index 0, a
/// normal defined only after the face that named it, and bad index text.
#[test]
fn bad_normal_and_texture_references_are_still_refused() {
    let cases = [
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//2 3//1\n",
            "5: face refers to normal 2, but only 1 normal is defined so far",
        ),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/2 3/1\n",
            "5: face refers to texture coordinate 2, but only 1 texture coordinate is defined \
             so far",
        ),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1//0 2//1 3//1\n",
            "4: face refers to normal 0, but only 0 normals are defined so far",
        ),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/0 2/1 3/1\n",
            "4: face refers to texture coordinate 0, but only 0 texture coordinates are defined \
             so far",
        ),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1//1 2//1 3//1\nvn 0 0 1\nf 1//1 2//1 3//1\n",
            "4: face refers to normal 1, but only 0 normals are defined so far",
        ),
        (
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1//x 2//1 3//1\n",
            "4: face normal index \"x\" is not an integer",
        ),
    ];
    for (obj, tail) in cases {
        let (e, p) = load(obj, &[]);
        let e = e.unwrap_err();
        assert_eq!(e, format!("{}:{tail}", p.display()), "{obj}");
    }
}

/// Unknown statements made of a word are skipped with one warning per keyword (its first line);
/// valid statements that draw nothing warn once per kind.
#[test]
fn unknown_and_unrendered_statements_are_skipped_with_a_warning() {
    let obj = "# exported with skin weights\n\
               v 0 0 0\nvw 1 0 0.5 1 0.5\n\
               v 1 0 0\nvw 2 0 1\n\
               v 0 1 0\nvw 3 0 1\n\
               Ka 1 2 3\n\
               f 1 2 3\n\
               l 1 2\np 3\n\
               cstype bspline\ndeg 3\ncurv 0 1 1 2 3\nparm u 0 0 0 1 1 1\nend\n\
               usemap tex\nlod 3\n";
    let (s, p) = load(obj, &[]);
    let s = s.unwrap();
    assert_eq!(s.mesh.triangle_count(), 1);
    let p = p.display();
    assert_eq!(
        s.warnings,
        vec![
            format!("{p}:3: unknown statement \"vw\" skipped"),
            format!("{p}:8: unknown statement \"Ka\" skipped"),
            format!(
                "{p}:10: point and line elements are not rendered; \"l\" and other point and \
                 line statements are skipped (only faces are rendered)"
            ),
            format!(
                "{p}:12: free-form curves and surfaces are not rendered; \"cstype\" and the \
                 other free-form statements are skipped (only polygon faces are rendered)"
            ),
            format!(
                "{p}:17: texture maps are not rendered; \"usemap\" statements are skipped \
                 (surfaces show their material's Kd colour)"
            ),
            format!(
                "{p}:18: display and render attributes are not supported; \"lod\" and similar \
                 statements are skipped"
            ),
        ]
    );
}

/// A file with many different unknown keywords: eight reported one by one, then a count.
#[test]
fn many_unknown_keywords_end_in_one_count() {
    let mut obj = String::from(TRIANGLE);
    for i in 0..12 {
        obj.push_str(&format!("kw{i} 1\nkw{i} 2\n"));
    }
    let (s, p) = load(&obj, &[]);
    let w = s.unwrap().warnings;
    assert_eq!(w.len(), 9, "{w:?}");
    assert_eq!(
        w[7],
        format!("{}:19: unknown statement \"kw7\" skipped", p.display())
    );
    assert_eq!(
        w[8],
        format!(
            "{}: 4 more unknown statement keywords skipped (the first, \"kw8\", at line 21); is \
             this really an OBJ file?",
            p.display()
        )
    );
}

/// Text that is not OBJ stays "not an OBJ file"; a byte-order mark, comments in another encoding
/// and Windows line ends are fine.
#[test]
fn non_text_is_still_not_an_obj() {
    let not_obj = |bytes: &[u8], line: u32, detail: &str| {
        let dir = scratch();
        let p = write(&dir, "x.obj", bytes);
        let e = load_scene(&p).unwrap_err().to_string();
        assert_eq!(
            e,
            format!("{}:{line}: not an OBJ file: {detail}", p.display()),
            "{bytes:?}"
        );
    };
    not_obj(b"v 0 0 0\nv\0 1 0 0\n", 2, "binary data");
    not_obj(b"v 0 0 0\n# nul \0 in a comment\n", 2, "binary data");
    not_obj(b"v 0 0 0\nv\xff 0 0 0\n", 2, "binary data");
    not_obj(b"\xe9t\xe9 0 0 0\n", 1, "binary data");
    not_obj(
        b"\xc3\xa9t\xc3\xa9 0 0 0\n",
        1,
        "unknown statement \"\u{e9}t\u{e9}\"",
    );
    not_obj(b"v 0 0 0\n\x01\x02\x03\n", 2, "binary data");
    not_obj(b"v 0 0 0\nv 0 \xff 0\n", 2, "binary data");
    not_obj(
        b"{\"meshes\": []}\n",
        1,
        "unknown statement \"{\"meshes\":\"",
    );
    not_obj(b"<!DOCTYPE html>\n", 1, "unknown statement \"<!DOCTYPE\"");
    not_obj(
        b"ply\nformat ascii 1.0\nend_header\n0 0 0\n",
        4,
        "unknown statement \"0\"",
    );
    let dir = scratch();
    let p = write(
        &dir,
        "x.obj",
        b"\xEF\xBB\xBF# Erstellt f\xfcr Sie\r\nv 0 0 0\r\nv 1 0 0 # \xe9\r\nv 0 1 0\r\nf 1 2 3\r\n",
    );
    let s = load_scene(&p).unwrap();
    assert_eq!(s.mesh.triangle_count(), 1);
    assert_eq!(s.warnings, Vec::<String>::new());
}
