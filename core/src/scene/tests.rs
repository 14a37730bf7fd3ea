//! Every bad scene gets one clear message naming the file and line or JSON field.

use super::*;

/// A fresh scratch folder per call, removed when dropped.
fn scratch() -> crate::scratch::Scratch {
    crate::scratch::Scratch::new("hort-scene-tests-")
}

fn write(dir: &Path, name: &str, text: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p
}

fn error_of(name: &str, text: &str) -> (String, PathBuf) {
    let dir = scratch();
    let p = write(&dir, name, text.as_bytes());
    let e = load_scene(&p).expect_err("must fail").to_string();
    (e, p)
}

const TRIANGLE: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

#[test]
fn missing_file_names_the_path() {
    let p = scratch().join("nope.obj");
    let e = load_scene(&p).unwrap_err().to_string();
    assert!(
        e.starts_with(&format!("cannot read {}: ", p.display())),
        "{e}"
    );
}

#[test]
fn binary_data_is_not_an_obj() {
    let dir = scratch();
    let p = write(&dir, "x.obj", &[0x89, b'P', b'N', b'G', 0xff, 0xfe, b'\n']);
    let e = load_scene(&p).unwrap_err().to_string();
    assert_eq!(
        e,
        format!("{}:1: not an OBJ file: binary data", p.display())
    );
}

#[test]
fn unknown_statement_is_not_an_obj() {
    let (e, p) = error_of("x.obj", "# hi\nv 0 0 0\n<html>\n");
    assert_eq!(
        e,
        format!(
            "{}:3: not an OBJ file: unknown statement \"<html>\"",
            p.display()
        )
    );
}

#[test]
fn face_index_out_of_range_names_line_and_counts() {
    let (e, p) = error_of("x.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n");
    assert_eq!(
        e,
        format!(
            "{}:4: face refers to vertex 4, but only 3 vertices are defined so far",
            p.display()
        )
    );
    let (e, p) = error_of("x.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -4 1 2\n");
    assert_eq!(
        e,
        format!(
            "{}:4: face refers to vertex -4, but only 3 vertices are defined so far",
            p.display()
        )
    );
    let (e, p) = error_of("x.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n");
    assert!(
        e.starts_with(&format!("{}:4: face refers to vertex 0,", p.display())),
        "{e}"
    );
    let (e, p) = error_of(
        "x.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//2 3//1\n",
    );
    assert_eq!(
        e,
        format!(
            "{}:5: face refers to normal 2, but only 1 normal is defined so far",
            p.display()
        )
    );
}

#[test]
fn non_finite_coordinates_name_the_line() {
    for bad in ["nan", "inf", "-inf", "NaN"] {
        let (e, p) = error_of("x.obj", &format!("v 0 0 0\nv 1 {bad} 0\n"));
        assert_eq!(
            e,
            format!(
                "{}:2: vertex has a non-finite coordinate ({bad})",
                p.display()
            )
        );
    }
    let (e, p) = error_of("x.obj", "v 0 0 0\nv 1 1e39 0\n");
    assert_eq!(
        e,
        format!(
            "{}:2: vertex has a non-finite coordinate (1e39)",
            p.display()
        )
    );
}

#[test]
fn syntax_errors_name_the_line() {
    let (e, p) = error_of("x.obj", "v 0 zero 0\n");
    assert_eq!(
        e,
        format!(
            "{}:1: vertex coordinate \"zero\" is not a number",
            p.display()
        )
    );
    let (e, p) = error_of("x.obj", "v 0 0\n");
    assert_eq!(
        e,
        format!("{}:1: vertex needs 3 coordinates, found 2", p.display())
    );
    let (e, p) = error_of("x.obj", "v 0 0 0\nv 1 0 0\nf 1 2\n");
    assert_eq!(
        e,
        format!("{}:3: face needs at least 3 corners, found 2", p.display())
    );
}

#[test]
fn zero_triangles_is_an_error() {
    let (e, p) = error_of("x.obj", "# only vertices\nv 0 0 0\nv 1 0 0\n");
    assert_eq!(
        e,
        format!("{}: the scene contains no triangles", p.display())
    );
}

#[test]
fn degenerate_scene_cannot_be_framed() {
    let (e, p) = error_of("x.obj", "v 1 1 1\nv 1 1 1\nv 1 1 1\nf 1 2 3\n");
    assert_eq!(
        e,
        format!(
            "{}: the scene has no extent (all vertices coincide), so it cannot be framed",
            p.display()
        )
    );
}

#[test]
fn polygons_fan_triangulate_in_file_order() {
    let dir = scratch();
    let p = write(
        &dir,
        "x.obj",
        b"v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nf 1 2 3 4\no b\nf 1 2 5\n",
    );
    let s = load_scene(&p).unwrap();
    assert_eq!(s.mesh.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 1, 4]]);
}

#[test]
fn materials_come_from_mtl_and_unknown_ones_warn() {
    let dir = scratch();
    write(&dir, "m.mtl", b"newmtl red\nKd 0.8 0.1 0.1\n");
    let p = write(
        &dir,
        "x.obj",
        format!("mtllib m.mtl\n{TRIANGLE}usemtl red\nf 1 2 3\nusemtl blue\nf 1 2 3\n").as_bytes(),
    );
    let s = load_scene(&p).unwrap();
    let kd: Vec<[f32; 3]> = s
        .mesh
        .triangle_materials
        .iter()
        .map(|&m| s.mesh.materials[m as usize].kd)
        .collect();
    assert_eq!(kd, vec![[0.7; 3], [0.8, 0.1, 0.1], [0.7; 3]]);
    assert_eq!(s.warnings.len(), 1);
    assert!(
        s.warnings[0].contains(":8: material \"blue\" is not defined"),
        "{:?}",
        s.warnings
    );
}

fn manifest_error(json: &str) -> (String, PathBuf) {
    let dir = scratch();
    write(&dir, "t.obj", TRIANGLE.as_bytes());
    let p = write(&dir, "s.json", json.as_bytes());
    (load_scene(&p).unwrap_err().to_string(), p)
}

#[test]
fn malformed_manifest_names_the_json_path() {
    let (e, p) = manifest_error(
        r#"{"meshes": ["t.obj"], "camera": {"eye": [0, 0, "x"], "look_at": [0,0,0]}}"#,
    );
    assert!(
        e.starts_with(&format!(
            "{}: manifest field `camera.eye[2]`: invalid type: string \"x\"",
            p.display()
        )),
        "{e}"
    );
    let (e, p) = manifest_error(r#"{"meshes": ["t.obj"], "widht": 5}"#);
    assert!(
        e.starts_with(&format!(
            "{}: manifest field `widht`: unknown field `widht`",
            p.display()
        )),
        "{e}"
    );
    let (e, p) = manifest_error(r#"{"meshes": ["t.obj"]"#);
    assert!(
        e.starts_with(&format!(
            "{}: manifest field `(root)`: EOF while parsing",
            p.display()
        )),
        "{e}"
    );
    let (e, p) = manifest_error(r#"{"meshes": []}"#);
    assert_eq!(
        e,
        format!(
            "{}: manifest field `meshes`: lists no OBJ files",
            p.display()
        )
    );
}

#[test]
fn unknown_light_kind_is_named() {
    let (e, p) = manifest_error(
        r#"{"meshes": ["t.obj"], "lights": [{"kind": "point", "position": [0,1,0], "intensity": 1}, {"kind": "spot"}]}"#,
    );
    assert!(
        e.starts_with(&format!(
            "{}: manifest field `lights[1].kind`: unknown variant `spot`, expected `point` or `directional`",
            p.display()
        )),
        "{e}"
    );
}

#[test]
fn bad_manifest_values_are_named() {
    let (e, p) = manifest_error(r#"{"meshes": ["t.obj"], "width": 0}"#);
    assert_eq!(
        e,
        format!(
            "{}: manifest field `width`: 0 is not between 1 and 65536",
            p.display()
        )
    );
    let (e, p) = manifest_error(
        r#"{"meshes": ["t.obj"], "camera": {"eye": [0,0,1], "look_at": [0,0,0], "vfov": 180}}"#,
    );
    assert_eq!(
        e,
        format!(
            "{}: manifest field `camera.vfov`: 180 is not between 0 and 180 degrees",
            p.display()
        )
    );
    let (e, p) = manifest_error(
        r#"{"meshes": ["t.obj"], "lights": [{"kind": "directional", "direction": [0,0,0], "irradiance": 1}]}"#,
    );
    assert_eq!(
        e,
        format!(
            "{}: manifest field `lights[0].direction`: must not be the zero vector",
            p.display()
        )
    );
    let (e, p) =
        manifest_error(r#"{"meshes": ["t.obj"], "materials": {"steel": {"kd": [1,1,1]}}}"#);
    assert_eq!(
        e,
        format!(
            "{}: manifest field `materials.steel`: no mesh uses a material of that name",
            p.display()
        )
    );
}

#[test]
fn manifest_mesh_errors_name_the_obj() {
    let (e, p) = manifest_error(r#"{"meshes": ["missing.obj"]}"#);
    let obj = p.parent().unwrap().join("missing.obj");
    assert!(
        e.starts_with(&format!("cannot read {}: ", obj.display())),
        "{e}"
    );
}

#[test]
fn manifest_overrides_defaults() {
    let dir = scratch();
    write(&dir, "t.obj", TRIANGLE.as_bytes());
    let p = write(
        &dir,
        "s.json",
        br#"{"meshes": ["t.obj", "t.obj"], "ambient": 0.25, "background": [0.1, 0.2, 0.3],
            "materials": {"default": {"kd": [0.5, 0.5, 0.5]}}, "width": 64, "height": 48, "spp": 4,
            "lights": [{"kind": "directional", "direction": [0, -2, 0], "irradiance": [1, 2, 3]}]}"#,
    );
    let s = load_scene(&p).unwrap();
    assert_eq!(s.mesh.triangle_count(), 2);
    assert_eq!(s.ambient, [0.25; 3]);
    assert_eq!(s.background, [0.1, 0.2, 0.3]);
    assert!(s.mesh.materials.iter().all(|m| m.kd == [0.5; 3]));
    assert_eq!(
        s.image,
        ImageSettings {
            width: Some(64),
            height: Some(48),
            spp: Some(4)
        }
    );
    assert_eq!(
        s.lights,
        vec![Light::Directional {
            direction: DVec3::new(0.0, -1.0, 0.0),
            irradiance: [1.0, 2.0, 3.0]
        }]
    );
}

#[test]
fn absurd_sizes_are_refused() {
    assert_eq!(
        check_image_size(0, 10, 1).unwrap_err().to_string(),
        "width = 0 is out of range: must be 1 to 65536"
    );
    assert_eq!(
        check_image_size(65536, 65536, 1).unwrap_err().to_string(),
        "width x height = 4294967296 is out of range: at most 134217728 pixels"
    );
    assert_eq!(
        check_image_size(64, 48, 0).unwrap_err().to_string(),
        "spp = 0 is out of range: must be 1 to 65536"
    );
    assert_eq!(
        check_image_size(16384, 8192, 65536)
            .unwrap_err()
            .to_string(),
        "width x height x spp = 8796093022208 is out of range: at most 17179869184 samples"
    );
    assert!(check_image_size(960, 540, 1).is_ok());
}

#[test]
fn bare_obj_is_framed_as_documented() {
    let dir = scratch();
    let p = write(&dir, "x.obj", b"v 0 0 0\nv 2 0 0\nv 0 2 2\nf 1 2 3\n");
    let s = load_scene(&p).unwrap();
    // The box's centre is the local origin: c in the file is 0 in the scene.
    assert_eq!(s.origin, DVec3::new(1.0, 1.0, 1.0));
    let c = DVec3::ZERO;
    let d = 12f64.sqrt();
    assert_eq!(s.camera.eye, c + DVec3::new(0.0, 0.5, 1.25) * d);
    assert_eq!(s.camera.look_at, c);
    assert_eq!(s.camera.vfov_degrees, 45.0);
    let light = c + DVec3::new(0.5, 1.0, 0.8) * d;
    let i = (std::f64::consts::PI * (light - c).length_squared()) as f32;
    assert_eq!(
        s.lights,
        vec![Light::Point {
            position: light,
            intensity: [i; 3]
        }]
    );
}

/// Positions are read in f64 and stored relative to the scene's centre: a triangle a million
/// units away keeps offsets that f32 at 1e6 (ulp 0.0625) could not hold, and a manifest's camera
/// and point light move into the same frame.
#[test]
fn far_scenes_are_stored_relative_to_their_centre() {
    let dir = scratch();
    write(
        &dir,
        "far.obj",
        b"v 1000000.001 -2000000 3000000.25\nv 1000000.003 -2000000 3000000.25\n\
          v 1000000.001 -1999999.998 3000000.25\nv 5e30 0 0\nf 1 2 3\n",
    );
    let p = write(
        &dir,
        "far.json",
        br#"{"meshes": ["far.obj"],
             "camera": {"eye": [1000000.002, -1999999.999, 3000001.25],
                        "look_at": [1000000.002, -1999999.999, 3000000.25]},
             "lights": [{"kind": "point", "position": [1000000.002, -1999999.999, 3000000.5],
                         "intensity": 1}]}"#,
    );
    let s = load_scene(&p).unwrap();
    // The unused vertex at 5e30 does not move the centre.
    let centre = DVec3::new(1000000.002, -1999999.999, 3000000.25);
    assert!((s.origin - centre).length() < 1e-9, "{:?}", s.origin);
    let local = |i: usize| s.mesh.positions[i].as_dvec3();
    for (i, expected) in [(0, [-0.001, -0.001, 0.0]), (1, [0.001, -0.001, 0.0])] {
        let d = local(i) - DVec3::from(expected);
        assert!(d.abs().max_element() < 1e-9, "vertex {i}: {:?}", local(i));
    }
    assert!((s.camera.eye - DVec3::new(0.0, 0.0, 1.0)).length() < 1e-9);
    assert!(s.camera.look_at.length() < 1e-9);
    let Light::Point { position, .. } = s.lights[0] else {
        panic!("point light expected")
    };
    assert!((position - DVec3::new(0.0, 0.0, 0.25)).length() < 1e-9);
}

/// Vertices farther from the centre than f32 can hold are refused, naming the file (here an
/// unused vertex 6e38 from a triangle at 3e38).
#[test]
fn scenes_wider_than_f32_are_refused() {
    let (e, p) = error_of(
        "wide.obj",
        "v 3e38 0 0\nv 3e38 1 0\nv 3e38 0 1\nv -3e38 0 0\nf 1 2 3\n",
    );
    assert_eq!(
        e,
        format!(
            "{}: the scene is too large: vertices lie farther than 3.4e38 from its centre, \
             beyond single precision",
            p.display()
        )
    );
}

/// Found by the bad input table: text after the manifest's JSON object was ignored.
#[test]
fn text_after_the_manifest_object_is_refused() {
    let (e, p) = manifest_error(r#"{"meshes": ["t.obj"]} trailing"#);
    assert_eq!(
        e,
        format!(
            "{}: manifest field `(root)`: trailing characters at line 1 column 23",
            p.display()
        )
    );
}

/// Found by the bad input table: a material library tobj refuses was reported without a line.
#[test]
fn a_malformed_material_library_names_the_line() {
    let dir = scratch();
    let mtl = write(&dir, "m.mtl", b"newmtl a\n# fine\nKd 0.5 x 0.5\n");
    let obj = write(
        &dir,
        "s.obj",
        format!("mtllib m.mtl\nusemtl a\n{TRIANGLE}").as_bytes(),
    );
    assert_eq!(
        load_scene(&obj).unwrap_err().to_string(),
        format!(
            "{}: material library: line 3: \"Kd 0.5 x 0.5\" is not a valid statement \
             (material parse error)",
            mtl.display()
        )
    );
}

/// Found by fuzzing (fuzz/, target `obj`): tobj 4.0.5 panics on a colour statement with fewer
/// than three values. One value is grey (the MTL rule); none or two is an error naming the line.
#[test]
fn short_colour_statements_are_grey_or_refused_never_a_panic() {
    let load = |mtl: &[u8]| {
        let dir = scratch();
        let mtl_path = write(&dir, "m.mtl", mtl);
        let obj = write(
            &dir,
            "s.obj",
            format!("mtllib m.mtl\nusemtl a\n{TRIANGLE}").as_bytes(),
        );
        (load_scene(&obj).map(|s| s.mesh.materials), mtl_path)
    };
    let (materials, _) = load(b"newmtl a\nKd 0.25\nKs 0.5\n");
    assert_eq!(materials.unwrap()[1].kd, [0.25; 3]);
    for (text, statement) in [
        (&b"newmtl a\nKd 0.8 0.1\n"[..], "Kd 0.8 0.1"),
        (b"newmtl a\n\nKa\n", "Ka"),
        (b"newmtl a\nKe 1 x\n", "Ke 1 x"),
    ] {
        let (result, path) = load(text);
        let line = if statement == "Ka" { 3 } else { 2 };
        assert_eq!(
            result.unwrap_err().to_string(),
            format!(
                "{}: material library: line {line}: \"{statement}\" needs 3 values (r g b) or 1 \
                 (grey)",
                path.display()
            )
        );
    }
    let (result, path) = load(b"newmtl a\nKd 1 1 1\n\xff\n");
    assert_eq!(
        result.unwrap_err().to_string(),
        format!(
            "{}: material library: not UTF-8 text (invalid UTF-8 at byte offset 18)",
            path.display()
        )
    );
}

/// Found by fuzzing (target `obj`): a material name holding a carriage return (old Mac line
/// ends) was echoed raw, so the warning spanned two lines. Names are quoted with escapes.
#[test]
fn names_with_control_characters_stay_on_one_line() {
    let dir = scratch();
    write(&dir, "m.mtl", b"newmtl red\rKs 0.5 0.5 0.5\nmap_Ks t.png\n");
    let obj = write(
        &dir,
        "s.obj",
        format!("mtllib m.mtl\nusemtl red\n{TRIANGLE}").as_bytes(),
    );
    let scene = load_scene(&obj).unwrap();
    assert_eq!(scene.warnings.len(), 2, "{:?}", scene.warnings);
    assert!(
        scene.warnings[0].contains(r#"material "red\rKs 0.5 0.5 0.5" uses a texture"#),
        "{}",
        scene.warnings[0]
    );
    assert!(
        scene.warnings[1].contains(r#"material "red" is not defined by any mtllib"#),
        "{}",
        scene.warnings[1]
    );
    let (e, _) = manifest_error(
        "{\"meshes\": [\"t.obj\"], \"materials\": {\"a\\rb\": {\"kd\": [1, 1, 1]}}}",
    );
    assert!(
        e.ends_with("manifest field `materials.a\\rb`: no mesh uses a material of that name"),
        "{e}"
    );
    let (e, _) = manifest_error("{\"meshes\": [\"t.obj\"], \"x\\ny\": 1}");
    assert!(
        !e.contains('\n') && e.contains("unknown field `x\\ny`"),
        "{e}"
    );
}

/// A 2 x 1 PNG: red then blue.
fn tiny_png() -> Vec<u8> {
    let mut png = Vec::new();
    image::RgbImage::from_fn(2, 1, |x, _| {
        image::Rgb(if x == 0 { [255, 0, 0] } else { [0, 0, 255] })
    })
    .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
    .unwrap();
    png
}

/// Faces of a textured material keep their texture coordinates (a polygon's fan triangles
/// each theirs); faces without `vt`, or of an untextured material, have none; one file named
/// by two materials is one texture.
#[test]
fn textured_faces_keep_their_coordinates_and_a_texture_is_loaded_once() {
    let dir = scratch();
    write(&dir, "t.png", &tiny_png());
    write(
        &dir,
        "m.mtl",
        b"newmtl a\nmap_Kd t.png\nnewmtl b\nKd 0.5 0.5 0.5\nmap_Kd -s 2 2 1 t.png\nnewmtl c\n",
    );
    let obj = write(
        &dir,
        "s.obj",
        b"mtllib m.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n\
          usemtl a\nf 1/1 2/2 3/3 4/4\nf 1 2 3\nusemtl b\nf 1/4 2/3 3/2\nusemtl c\nf 1/1 2/2 3/3\n",
    );
    let mesh = load_scene(&obj).unwrap().mesh;
    assert_eq!(mesh.textures.len(), 1);
    assert_eq!((mesh.textures[0].width, mesh.textures[0].height), (2, 1));
    assert_eq!(
        mesh.triangle_texcoords,
        vec![
            [0, 1, 2],
            [0, 2, 3],
            [NO_TEXCOORD; 3],
            [3, 2, 1],
            [NO_TEXCOORD; 3]
        ]
    );
    assert_eq!(mesh.texture_of(1).map(|(t, _)| t), Some(0));
    assert_eq!(mesh.texture_of(2), None);
    assert_eq!(
        mesh.texture_of(3),
        Some((0, [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0]]))
    );
    assert_eq!(mesh.texture_of(4), None);

    // Without a textured material, texture coordinates are not kept at all.
    let plain = write(
        &dir,
        "p.obj",
        b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/1 2/1 3/1\n",
    );
    let mesh = load_scene(&plain).unwrap().mesh;
    assert!(mesh.texcoords.is_empty() && mesh.triangle_texcoords.is_empty());
    let _ = std::fs::remove_dir_all(&dir);
}
