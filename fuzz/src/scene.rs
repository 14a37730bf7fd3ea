//! The scene targets: OBJ (with one MTL library) and the JSON manifest, loaded from files the way
//! `hort render` loads them.

use hort_core::scene::{Scene, load_scene, parse_manifest};

use crate::{assert_one_line, scratch};

/// Separates the OBJ text from the MTL text in an `obj` input.
pub const MTL_MARKER: &[u8] = b"\n#MTL\n";

/// The OBJ a manifest input can name (`a.obj`, a unit triangle with a material from `m.mtl`).
const MANIFEST_OBJ: &str = "mtllib m.mtl\nusemtl red\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
const MANIFEST_MTL: &str = "newmtl red\nKd 0.8 0.1 0.1\n";

/// OBJ target: the input up to [`MTL_MARKER`] is `scene.obj`, the rest is `m.mtl`, and
/// `scene.obj` is loaded as a scene. Inputs whose `mtllib` names a file outside the scratch
/// folder are skipped (they could name `/dev/zero`, which a user may do but a fuzzer must not).
pub fn obj(data: &[u8]) {
    let (obj, mtl) = scratch::cut(data, MTL_MARKER);
    let libraries_inside = obj.split(|&b| b == b'\n').all(|line| {
        let text = String::from_utf8_lossy(line);
        let mut words = text.split_ascii_whitespace();
        words.next() != Some("mtllib") || words.all(scratch::is_plain)
    });
    if !libraries_inside {
        return;
    }
    scratch::write("m.mtl", mtl);
    let path = scratch::write("scene.obj", obj);
    check(load_scene(&path), "OBJ");
}

/// Manifest target: the input is `scene.json` beside `a.obj` and `m.mtl`, and is loaded as a
/// scene. Manifests naming meshes outside the scratch folder are only parsed.
pub fn manifest(data: &[u8]) {
    let path = scratch::dir().join("scene.json");
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    match parse_manifest(text, &path) {
        Err(e) => assert_one_line("manifest", &e.to_string()),
        Ok(m) if m.meshes.iter().all(|f| scratch::is_plain(f)) => {
            scratch::write("a.obj", MANIFEST_OBJ.as_bytes());
            scratch::write("m.mtl", MANIFEST_MTL.as_bytes());
            scratch::write("scene.json", data);
            check(load_scene(&path), "manifest");
        }
        Ok(_) => {}
    }
}

/// Checks what a scene load returned: a one-line error, or a scene the renderer can use.
fn check(result: Result<Scene, hort_core::error::SceneError>, what: &str) {
    let scene = match result {
        Err(e) => return assert_one_line(what, &e.to_string()),
        Ok(scene) => scene,
    };
    let mesh = &scene.mesh;
    assert!(
        !mesh.triangles.is_empty(),
        "{what}: a scene without triangles loaded"
    );
    assert!(
        mesh.positions.iter().all(|p| p.is_finite()),
        "{what}: a non-finite vertex loaded"
    );
    let vertices = mesh.positions.len();
    assert!(
        mesh.triangles
            .iter()
            .flatten()
            .all(|&i| (i as usize) < vertices),
        "{what}: a vertex index is out of range"
    );
    assert_eq!(mesh.triangle_normals.len(), mesh.triangles.len());
    assert_eq!(mesh.triangle_materials.len(), mesh.triangles.len());
    assert!(
        mesh.triangle_normals
            .iter()
            .flatten()
            .all(|&i| { i == hort_core::scene::NO_NORMAL || (i as usize) < mesh.normals.len() }),
        "{what}: a normal index is out of range"
    );
    assert!(
        mesh.triangle_materials
            .iter()
            .all(|&m| (m as usize) < mesh.materials.len()),
        "{what}: a material index is out of range"
    );
    let camera = scene.camera_for(64, 48);
    assert!(
        camera.eye.is_finite() && camera.look_at.is_finite() && camera.up.is_finite(),
        "{what}: the camera is not finite: {camera:?}"
    );
    for w in &scene.warnings {
        assert_one_line(what, w);
    }
}
