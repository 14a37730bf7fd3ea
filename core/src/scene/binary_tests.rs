//! The binary scene: exact round trips and every validation error, with its exact text.

use super::*;
use glam::Vec3;

/// The repository's `scenes/` folder.
fn scenes() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes")
}

/// Every field of `a` and `b`, floats by their bits. (`Debug` prints the shortest decimal that
/// reads back to the same f32 or f64, and `-0.0` as such, so equal text means equal bits for
/// finite values; the mesh arrays are compared by bits as well.)
fn assert_same(a: &Scene, b: &Scene) {
    let bits = |v: &[Vec3]| -> Vec<[u32; 3]> {
        v.iter().map(|p| p.to_array().map(f32::to_bits)).collect()
    };
    assert_eq!(bits(&a.mesh.positions), bits(&b.mesh.positions));
    assert_eq!(bits(&a.mesh.normals), bits(&b.mesh.normals));
    assert_eq!(a.mesh.triangles, b.mesh.triangles);
    assert_eq!(a.mesh.triangle_normals, b.mesh.triangle_normals);
    assert_eq!(a.mesh.triangle_materials, b.mesh.triangle_materials);
    assert_eq!(
        a.origin.to_array().map(f64::to_bits),
        b.origin.to_array().map(f64::to_bits)
    );
    assert_eq!(format!("{a:?}"), format!("{b:?}"));
}

#[test]
fn bundled_scenes_round_trip_bit_for_bit() {
    for rel in [
        "bunny/bunny.json",
        "bunny/bunny.obj",
        "cornell/cornell.json",
        "teapot/teapot.json",
        "stability/coplanar.json",
        "stability/degenerate.json",
        "stability/grazing.json",
        "stability/closed_sphere.obj",
    ] {
        let scene = load_scene(&scenes().join(rel)).unwrap();
        let bytes = encode_scene(&scene);
        let decoded = decode_scene(rel, &bytes).unwrap();
        assert_same(&scene, &decoded);
        assert_eq!(encode_scene(&decoded), bytes, "{rel}: re-encoding differs");
    }
}

/// A scene with one of everything the loaders never combine: a directional light beside a
/// point light, vertex normals on some corners, image settings, warnings, negative zeros.
fn tiny() -> Scene {
    Scene {
        source: PathBuf::from("t.obj"),
        origin: DVec3::new(1e6, -0.0, 0.1),
        mesh: Mesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(0.0, -0.0, 1.5e-40)],
            normals: vec![Vec3::Y],
            triangles: vec![[0, 1, 2]],
            triangle_normals: vec![[0, NO_NORMAL, 0]],
            triangle_materials: vec![0],
            materials: vec![Material {
                name: "m".into(),
                kd: [0.7, 0.25, 1.0],
                texture: Some(0),
            }],
            texcoords: vec![[0.25, -0.0], [1e9, 0.5]],
            triangle_texcoords: vec![[0, 1, 0]],
            textures: vec![std::sync::Arc::new(crate::texture::Texture::new(
                "wood.png".into(),
                2,
                1,
                vec![1, 2, 3, 250, 251, 252],
            ))],
        },
        camera: CameraSpec {
            eye: DVec3::new(0.0, 0.0, 5.0),
            look_at: DVec3::ZERO,
            up: DVec3::Y,
            vfov_degrees: 45.0,
        },
        framed_bounds: None,
        lights: vec![
            Light::Point {
                position: DVec3::new(1.0, 2.0, 3.0),
                intensity: [10.0; 3],
            },
            Light::Directional {
                direction: DVec3::NEG_Y,
                irradiance: [0.5, 0.6, 0.7],
            },
        ],
        ambient: [0.01, 0.0, -0.0],
        background: [0.1, 0.2, 0.3],
        image: ImageSettings {
            width: Some(64),
            height: None,
            spp: Some(4),
        },
        warnings: vec!["t.obj:3: unknown statement".into()],
        animation: None,
    }
}

#[test]
fn every_field_round_trips_and_encoding_is_deterministic() {
    let mut scene = tiny();
    let bytes = encode_scene(&scene);
    assert_same(&scene, &decode_scene("t", &bytes).unwrap());
    assert_eq!(encode_scene(&scene), bytes);
    assert_eq!(&bytes[..8], b"HORTSCN\0");
    assert_eq!(&bytes[8..12], &[2, 0, 0, 0]);
    let body = (bytes.len() - SCENE_BINARY_HEADER_LEN) as u64;
    assert_eq!(&bytes[12..20], &body.to_le_bytes());
    scene.framed_bounds = Some((DVec3::splat(-1.0), DVec3::splat(2.0)));
    scene.image = ImageSettings::default();
    scene.warnings.clear();
    let bytes = encode_scene(&scene);
    assert_same(&scene, &decode_scene("t", &bytes).unwrap());
    // A scene with camera keyframes stores them after the textures, every f64 bit for bit.
    let key = |frame: u32, eye: [f64; 3]| crate::animation::CameraKey {
        frame,
        camera: crate::scene::CameraSpec {
            eye: DVec3::from_array(eye),
            look_at: DVec3::new(0.1, 1.0 / 3.0, -2e-300),
            up: DVec3::Y,
            vfov_degrees: 47.123_456_789_012_34,
        },
    };
    let animation = crate::animation::Animation {
        frames: 30,
        path: crate::animation::CameraPath::Keyframes {
            keys: vec![key(0, [5.0, 2.5, 0.1 + 0.2]), key(29, [-5.0, 1e-17, 7.0])],
        },
    };
    scene.animation = Some(animation.clone());
    let with = encode_scene(&scene);
    assert!(with.len() > bytes.len());
    let decoded = decode_scene("t", &with).unwrap();
    assert_same(&scene, &decoded);
    let bits = |a: &crate::animation::Animation| match &a.path {
        crate::animation::CameraPath::Keyframes { keys } => keys
            .iter()
            .flat_map(|k| {
                let c = k.camera;
                [c.eye, c.look_at, c.up]
                    .into_iter()
                    .flat_map(|v| v.to_array())
                    .chain([c.vfov_degrees])
                    .map(f64::to_bits)
            })
            .collect::<Vec<u64>>(),
        _ => Vec::new(),
    };
    assert_eq!(bits(decoded.animation.as_ref().unwrap()), bits(&animation));
}

/// `tiny()` without the directional light, warnings, image settings and textures: the offsets
/// below.
fn small() -> Vec<u8> {
    let mut s = tiny();
    s.lights.truncate(1);
    s.image = ImageSettings::default();
    s.warnings.clear();
    s.mesh.texcoords.clear();
    s.mesh.triangle_texcoords.clear();
    s.mesh.textures.clear();
    s.mesh.materials[0].texture = None;
    let bytes = encode_scene(&s);
    assert_eq!(bytes.len(), 352);
    bytes
}

// Byte offsets in `small()`: origin 24, source 48 (length) and 52, triangle count 57,
// triangles 65, triangle_normals 77, triangle_materials 89, positions count 93, positions 101,
// normals count 137, normals 145, materials count 157, name 161, kd 166, camera eye 178,
// look_at 202, up 226, vfov 250, framed_bounds 258, lights count 259, kind 263, position 264,
// intensity 288, ambient 300, background 312, width 324, height 325, spp 326, warnings 327,
// texcoords count 331, triangle_texcoords count 339, materials[0].texture 347, textures count
// 348.

/// Recomputes the body length and checksum after the body was edited.
fn reseal(mut bytes: Vec<u8>) -> Vec<u8> {
    let body = (bytes.len() - SCENE_BINARY_HEADER_LEN) as u64;
    bytes[12..20].copy_from_slice(&body.to_le_bytes());
    let mut h = crc32fast::Hasher::new();
    h.update(&bytes[..20]);
    h.update(&bytes[SCENE_BINARY_HEADER_LEN..]);
    let crc = h.finalize();
    bytes[20..24].copy_from_slice(&crc.to_le_bytes());
    bytes
}

fn error(bytes: &[u8]) -> String {
    decode_scene("jobs/j/scene/scene.bin", bytes)
        .unwrap_err()
        .to_string()
}

/// `small()` with `value` written at `at`, resealed.
fn edited(at: usize, value: &[u8]) -> String {
    let mut bytes = small();
    bytes[at..at + value.len()].copy_from_slice(value);
    error(&reseal(bytes))
}

#[test]
fn the_offsets_of_small_are_as_documented() {
    let bytes = small();
    assert_eq!(&bytes[52..57], b"t.obj");
    assert_eq!(&bytes[57..65], &1u64.to_le_bytes());
    assert_eq!(&bytes[93..101], &3u64.to_le_bytes());
    assert_eq!(&bytes[137..145], &1u64.to_le_bytes());
    assert_eq!(&bytes[157..161], &1u32.to_le_bytes());
    assert_eq!(bytes[165], b'm');
    assert_eq!(&bytes[250..258], &45f64.to_le_bytes());
    assert_eq!(&bytes[259..263], &1u32.to_le_bytes());
    assert_eq!(&bytes[327..331], &0u32.to_le_bytes());
    assert_eq!(&bytes[331..347], &[0; 16]);
    assert_eq!(&bytes[347..352], &[0; 5]);
}

#[test]
fn header_errors_name_the_object_and_the_byte() {
    let name = "jobs/j/scene/scene.bin";
    assert_eq!(
        error(&small()[..10]),
        format!("{name}: 10 bytes, shorter than the 24-byte header of a binary scene")
    );
    let mut bytes = small();
    bytes[..8].copy_from_slice(b"HORTBLK\0");
    assert_eq!(
        error(&bytes),
        format!(
            "{name}: not a binary scene: bytes 0..8 are \"HORTBLK\\x00\", expected \"HORTSCN\\x00\""
        )
    );
    let mut bytes = small();
    bytes[8] = 1;
    assert_eq!(
        error(&bytes),
        format!(
            "{name}: format version 1 at byte 8 is not supported: this build reads version 2 only"
        )
    );
    let mut bytes = small();
    bytes[10] = 1;
    assert_eq!(
        error(&bytes),
        format!("{name}: reserved field at byte 10 is 1, expected 0")
    );
    let bytes = small();
    assert_eq!(
        error(&bytes[..300]),
        format!("{name}: body length at byte 12 declares 328 bytes, but 276 follow the header")
    );
    let mut bytes = small();
    bytes[200] ^= 0x10;
    let e = error(&bytes);
    assert!(
        e.starts_with(&format!("{name}: checksum at byte 20 is 0x"))
            && e.ends_with(": the object is corrupt"),
        "{e}"
    );
}

#[test]
fn every_single_bit_flip_is_refused() {
    for bytes in [small(), encode_scene(&tiny())] {
        every_bit_flip_is_refused(&bytes);
    }
}

fn every_bit_flip_is_refused(bytes: &[u8]) {
    for byte in 0..bytes.len() {
        for bit in 0..8 {
            let mut b = bytes.to_vec();
            b[byte] ^= 1 << bit;
            assert!(decode_scene("x", &b).is_err(), "byte {byte} bit {bit}");
        }
    }
}

#[test]
fn body_errors_name_the_field_and_its_byte() {
    let name = "jobs/j/scene/scene.bin";
    let cases: Vec<(usize, Vec<u8>, &str)> = vec![
        (
            24,
            f64::NAN.to_le_bytes().to_vec(),
            "byte 24: origin is [NaN, -0, 0.1], not finite",
        ),
        (53, vec![0xff], "byte 48: source is not valid UTF-8"),
        (
            48,
            400u32.to_le_bytes().to_vec(),
            "byte 52: source needs 400 bytes, but only 300 are left",
        ),
        (
            57,
            0u64.to_le_bytes().to_vec(),
            "byte 57: triangle count is 0, but a scene has at least one triangle",
        ),
        (
            57,
            u64::MAX.to_le_bytes().to_vec(),
            "byte 57: triangle count is 18446744073709551615, but only 287 bytes are left",
        ),
        (
            69,
            3u32.to_le_bytes().to_vec(),
            "byte 69: triangles[0][1] is 3, but there are 3 positions",
        ),
        (
            81,
            1u32.to_le_bytes().to_vec(),
            "byte 81: triangle_normals[0][1] is 1, but there are 1 normals",
        ),
        (
            89,
            1u32.to_le_bytes().to_vec(),
            "byte 89: triangle_materials[0] is 1, but there are 1 materials",
        ),
        (
            93,
            100u64.to_le_bytes().to_vec(),
            "byte 93: positions count is 100, but only 251 bytes are left",
        ),
        (
            121,
            f32::INFINITY.to_le_bytes().to_vec(),
            "byte 113: positions[1] is [1, 0, inf], not finite",
        ),
        (
            153,
            f32::NAN.to_le_bytes().to_vec(),
            "byte 145: normals[0] is [0, 1, NaN], not finite",
        ),
        (
            157,
            u32::MAX.to_le_bytes().to_vec(),
            "byte 157: materials count is 4294967295, but only 191 bytes are left",
        ),
        (
            170,
            f32::NAN.to_le_bytes().to_vec(),
            "byte 166: materials[0].kd is [0.7, NaN, 1.0], not finite",
        ),
        (
            250,
            f64::INFINITY.to_le_bytes().to_vec(),
            "byte 250: camera.vfov_degrees is inf, not finite",
        ),
        (
            258,
            vec![2],
            "byte 258: framed_bounds flag is 2, expected 0 or 1",
        ),
        (
            263,
            vec![7],
            "byte 263: lights[0].kind is 7, expected 0 (point) or 1 (directional)",
        ),
        (
            288,
            f32::NEG_INFINITY.to_le_bytes().to_vec(),
            "byte 288: lights[0].intensity is [-inf, 10.0, 10.0], not finite",
        ),
        (324, vec![9], "byte 324: width flag is 9, expected 0 or 1"),
        (
            327,
            6u32.to_le_bytes().to_vec(),
            "byte 327: warnings count is 6, but only 21 bytes are left",
        ),
        (
            347,
            vec![2],
            "byte 347: materials[0].texture flag is 2, expected 0 or 1",
        ),
    ];
    for (at, value, detail) in cases {
        assert_eq!(edited(at, &value), format!("{name}: {detail}"), "byte {at}");
    }
    let mut longer = small();
    longer.extend_from_slice(&[0, 0]);
    assert_eq!(
        error(&reseal(longer)),
        format!("{name}: byte 352: animation length needs 4 bytes, but only 2 are left")
    );
    let mut garbage = small();
    garbage.extend_from_slice(&2u32.to_le_bytes());
    garbage.extend_from_slice(b"{}");
    assert_eq!(
        error(&reseal(garbage)),
        format!(
            "{name}: byte 352: animation is not an animation: missing field `frames` at line 1 \
             column 2"
        )
    );
    let mut trailing = small();
    trailing.extend_from_slice(&2u32.to_le_bytes());
    trailing
        .extend_from_slice(b"{\"frames\": 3, \"path\": {\"kind\": \"orbit\", \"degrees\": 90}}x");
    trailing.splice(352..356, 55u32.to_le_bytes());
    assert_eq!(
        error(&reseal(trailing)),
        format!("{name}: byte 411: 1 bytes follow the last field (animation)")
    );
    let mut shorter = small();
    shorter.pop();
    assert_eq!(
        error(&reseal(shorter)),
        format!("{name}: byte 348: textures count needs 4 bytes, but only 3 are left")
    );
}

#[test]
fn a_named_encoding_is_the_encoding_of_the_scene_renamed_without_warnings() {
    let scene = tiny();
    assert!(
        !scene.warnings.is_empty(),
        "the test needs warnings to drop"
    );
    let renamed = Scene {
        source: PathBuf::from("main.json"),
        warnings: Vec::new(),
        ..scene.clone()
    };
    let named = encode_scene_named(&scene, "main.json");
    assert_eq!(named, encode_scene(&renamed));
    assert_same(&decode_scene("named", &named).unwrap(), &renamed);
}

/// The texture section's checks, on scenes an encoder would never write: each error names the
/// field and its byte.
#[test]
fn texture_errors_name_the_field() {
    let check = |edit: &dyn Fn(&mut Scene), expected: &str| {
        let mut scene = tiny();
        edit(&mut scene);
        let err = error(&encode_scene(&scene));
        assert!(err.ends_with(expected), "{err}\nexpected …{expected}");
    };
    check(
        &|s| s.mesh.materials[0].texture = Some(1),
        "\"m\"'s texture is 1, but there are 1 textures",
    );
    check(
        &|s| s.mesh.triangle_texcoords[0][2] = 2,
        "triangle_texcoords[0][2] is 2, but there are 2 texcoords",
    );
    check(
        &|s| s.mesh.triangle_texcoords.push([0; 3]),
        "triangle_texcoords count is 2, expected 0 or the triangle count 1",
    );
    check(
        &|s| s.mesh.texcoords[1][0] = f32::NAN,
        "texcoords[1] is [NaN, 0.5], not finite",
    );
    check(
        &|s| {
            s.mesh.materials[0].texture = None;
            s.mesh.textures.clear();
        },
        "triangle_texcoords[0] gives texture coordinates to a triangle whose material has no \
         texture",
    );
    check(
        &|s| {
            let t = std::sync::Arc::make_mut(&mut s.mesh.textures[0]);
            t.width = 3;
        },
        "textures[0].texels needs 9 bytes, but only 6 are left",
    );
}
