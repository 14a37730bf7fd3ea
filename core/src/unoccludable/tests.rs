use super::*;
use crate::scene::parse_obj;
use glam::DVec3;

fn mesh(obj: &str) -> Mesh {
    parse_obj(
        obj.as_bytes(),
        std::path::Path::new("t.obj"),
        &mut Vec::new(),
    )
    .unwrap()
}

fn point(x: f64, y: f64, z: f64) -> Light {
    Light::Point {
        position: DVec3::new(x, y, z),
        intensity: [1.0; 3],
    }
}

fn sun(direction: DVec3) -> Light {
    Light::Directional {
        direction,
        irradiance: [1.0; 3],
    }
}

/// A closed unit cube around the origin (faces wound either way: sides do not matter).
const CUBE: &str = "v -1 -1 -1\nv 1 -1 -1\nv 1 1 -1\nv -1 1 -1\nv -1 -1 1\nv 1 -1 1\nv 1 1 1\n\
    v -1 1 1\nf 1 2 3\nf 1 3 4\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 4 3 7\nf 4 7 8\n\
    f 1 4 8\nf 1 8 5\nf 2 3 7\nf 2 7 6\n";

const GROUND: &str = "v -5 0 -5\nv 5 0 -5\nv 5 0 5\nv -5 0 5\nf 1 2 3\nf 1 3 4\n";

#[test]
fn a_light_inside_a_convex_room_or_over_a_plane_cannot_be_occluded() {
    let room = mesh(CUBE);
    assert_eq!(
        unoccludable_lights(&room, &[point(0.0, 0.5, 0.0), point(0.9, -0.9, 0.2)]),
        [true, true]
    );
    let ground = mesh(GROUND);
    assert_eq!(
        unoccludable_lights(
            &ground,
            &[point(0.0, 3.0, 0.0), sun(DVec3::new(0.0, -1.0, 0.0))]
        ),
        [true, true]
    );
}

#[test]
fn anything_that_can_cast_a_shadow_makes_the_light_occludable() {
    // Light outside the cube: the far faces are behind the near ones.
    assert_eq!(
        unoccludable_lights(&mesh(CUBE), &[point(0.0, 3.0, 0.0)]),
        [false]
    );
    // A small quad floating over the ground casts a shadow on it.
    let caster = format!("{GROUND}v -1 1 -1\nv 1 1 -1\nv 1 1 1\nv -1 1 1\nf 5 6 7\nf 5 7 8\n");
    assert_eq!(
        unoccludable_lights(
            &mesh(&caster),
            &[point(0.0, 3.0, 0.0), sun(DVec3::new(0.0, -1.0, 0.0))]
        ),
        [false, false]
    );
    // A light in a triangle's plane (a segment could run along it) is not skipped either.
    assert_eq!(
        unoccludable_lights(&mesh(GROUND), &[point(9.0, 0.0, 0.0)]),
        [false]
    );
}

#[test]
fn no_triangles_occlude_nothing() {
    let empty = Mesh::default();
    assert_eq!(unoccludable_lights(&empty, &[point(0.0, 1.0, 0.0)]), [true]);
}

/// Inside the cube room, with the light inside too, shading every camera sample without the
/// light's shadow rays gives the same bits as tracing them.
#[test]
fn skipping_the_shadow_rays_changes_no_pixel() {
    use crate::camera::Camera;
    use crate::render::{ShadingScratch, build_scene_bvh, shade_batch};
    let scratch = tempfile::tempdir().unwrap();
    let dir = scratch.path();
    std::fs::write(dir.join("room.obj"), CUBE).unwrap();
    std::fs::write(
        dir.join("room.json"),
        r#"{"meshes": ["room.obj"], "camera": {"eye": [0.2, -0.3, 0.9], "look_at": [-0.4, 0.1, -1]},
            "lights": [{"kind": "point", "position": [0.3, 0.6, 0.2], "intensity": 2.0},
                       {"kind": "directional", "direction": [0, -1, 0], "irradiance": 0.5}]}"#,
    )
    .unwrap();
    let scene = crate::scene::load_scene(&dir.join("room.json")).unwrap();
    let free = unoccludable_lights(&scene.mesh, &scene.lights);
    // The sun shines through the ceiling from outside: the ceiling occludes it.
    assert_eq!(free, [true, false]);
    let bvh = build_scene_bvh(&scene.mesh);
    let (w, h) = (48u32, 32u32);
    let camera = Camera::new(&scene.camera_for(w, h), w, h).unwrap();
    let mut rays = Vec::new();
    let order = crate::sampling::TraceOrder::new(4);
    for pixel in 0..u64::from(w * h) {
        camera.pixels_rays(&[pixel], &order, &mut rays);
    }
    let mut hits = vec![None; rays.len()];
    bvh.closest_hits(&rays, &mut hits);
    assert!(
        hits.iter().all(Option::is_some),
        "the room surrounds the eye"
    );
    let batch = (rays.as_slice(), hits.as_slice());
    let mut lists = (ShadingScratch::default(), ShadingScratch::default());
    let skipping = shade_batch(&scene, &bvh, &free, batch, &mut lists.0);
    let tracing = shade_batch(&scene, &bvh, &[false, false], batch, &mut lists.1);
    assert_eq!(skipping, tracing);
    let lit = skipping.iter().filter(|c| c[0] > 0.0).count();
    assert!(lit > rays.len() / 2, "most samples see the light ({lit})");
}

/// Vertex normals along the plane normal keep a light over the ground unoccludable; normals
/// bent off it (smooth shading, whose shadow rays may start off the surface and reach lights
/// behind the triangle) make it occludable.
#[test]
fn bent_vertex_normals_make_every_light_occludable() {
    let light = [point(0.0, 3.0, 0.0), sun(DVec3::NEG_Y)];
    let flat = mesh(&format!(
        "{GROUND}vn 0 1 0\nvn 0 -2 0\nf 1//1 2//1 3//1\nf 1//2 3//2 4//2\n"
    ));
    assert_eq!(unoccludable_lights(&flat, &light), [true, true]);
    let mixed = mesh(&format!("{GROUND}vn 0 1 0\nvn 0 -1 0\nf 1//1 2//2 3//1\n"));
    assert_eq!(unoccludable_lights(&mixed, &light), [false, false]);
    let bent = mesh(&format!(
        "{GROUND}vn 0 1 0\nvn 0.1 1 0\nf 1//1 2//2 3//1\nf 1 3 4\n"
    ));
    assert_eq!(unoccludable_lights(&bent, &light), [false, false]);
}
