//! Camera paths: orbits turn the eye about the vertical axis, keyframed paths pass through their
//! keys and never leave a segment's bounds, and every invalid animation gets one clear message.

use super::spline::unclamped_segment;
use super::*;
use crate::scene::load_scene;
use std::path::PathBuf;

fn spec(eye: [f64; 3], look_at: [f64; 3]) -> CameraSpec {
    CameraSpec {
        eye: DVec3::from(eye),
        look_at: DVec3::from(look_at),
        up: DVec3::Y,
        vfov_degrees: 45.0,
    }
}

/// A camera's fields as their bits, to compare bit for bit (a zero's sign included).
fn bits(c: &CameraSpec) -> [u64; 10] {
    let [a, b, d] = c.eye.to_array().map(f64::to_bits);
    let [e, f, g] = c.look_at.to_array().map(f64::to_bits);
    let [h, i, j] = c.up.to_array().map(f64::to_bits);
    [a, b, d, e, f, g, h, i, j, c.vfov_degrees.to_bits()]
}

fn orbit(degrees: f64, frames: u32) -> Animation {
    Animation {
        frames,
        path: CameraPath::Orbit { degrees },
    }
}

fn keyed(frames: u32, keys: &[(u32, CameraSpec)]) -> Animation {
    Animation {
        frames,
        path: CameraPath::Keyframes {
            keys: keys
                .iter()
                .map(|&(frame, camera)| CameraKey { frame, camera })
                .collect(),
        },
    }
}

fn error(a: &Animation, base: &CameraSpec, frame: u32) -> String {
    a.camera(base, frame).unwrap_err().to_string()
}

fn invalid(a: &Animation) -> String {
    a.validate().unwrap_err().to_string()
}

/// An awkward base camera: an eye off every axis, a negative zero, a tilted up.
fn base() -> CameraSpec {
    CameraSpec {
        eye: DVec3::new(0.1, 0.7, -0.0),
        look_at: DVec3::new(3.3, 0.2, 1.0 / 3.0),
        up: DVec3::new(0.1, 1.0, 0.0),
        vfov_degrees: 37.5,
    }
}

#[test]
fn an_orbits_frame_zero_is_the_base_camera_bit_for_bit() {
    let base = base();
    for degrees in [360.0, -90.0, 1e-300, 0.0] {
        let got = orbit(degrees, 7).camera(&base, 0).unwrap();
        assert_eq!(bits(&got), bits(&base), "{degrees} degrees");
    }
    // An orbit by 0 degrees holds at every frame.
    let got = orbit(0.0, 7).camera(&base, 5).unwrap();
    assert_eq!(bits(&got), bits(&base));
}

/// 360 degrees over 4 frames: frame 1 turns the eye a quarter turn counter-clockwise seen from
/// above (+z to +x), keeping its distance to the axis and (exactly) its height, and nothing else
/// changes.
#[test]
fn an_orbit_turns_the_eye_about_the_vertical_axis_through_look_at() {
    let base = CameraSpec {
        eye: DVec3::new(1.0, 2.5, 4.0 + 3.0),
        look_at: DVec3::new(1.0, 0.5, 3.0),
        up: DVec3::Y,
        vfov_degrees: 40.0,
    };
    let a = orbit(360.0, 4);
    let radius = |c: &CameraSpec| {
        let d = c.eye - c.look_at;
        (d.x * d.x + d.z * d.z).sqrt()
    };
    let expected = [
        DVec3::new(1.0, 2.5, 7.0),
        DVec3::new(5.0, 2.5, 3.0),
        DVec3::new(1.0, 2.5, -1.0),
        DVec3::new(-3.0, 2.5, 3.0),
    ];
    for (frame, want) in (0u32..).zip(expected) {
        let got = a.camera(&base, frame).unwrap();
        assert!(
            (got.eye - want).abs().max_element() < 1e-12,
            "frame {frame}: {:?}",
            got.eye
        );
        assert_eq!(got.eye.y.to_bits(), base.eye.y.to_bits(), "frame {frame}");
        assert!((radius(&got) - 4.0).abs() < 1e-12, "frame {frame}");
        let rest = |c: &CameraSpec| (c.look_at, c.up, c.vfov_degrees.to_bits());
        assert_eq!(rest(&got), rest(&base), "frame {frame}");
    }
    // Negative degrees turn clockwise: +z to -x.
    let got = orbit(-360.0, 4).camera(&base, 1).unwrap();
    assert!((got.eye - DVec3::new(-3.0, 2.5, 3.0)).abs().max_element() < 1e-12);
}

/// A hairpin: out along +x, a short step in z, back along -x, then up. Unclamped centripetal
/// Catmull-Rom overshoots the keys' bounds here.
fn hairpin() -> Animation {
    keyed(
        400,
        &[
            (0, spec([0.0, 0.0, 0.0], [0.0, 0.0, -10.0])),
            (100, spec([10.0, 0.0, 0.0], [10.0, 0.0, -10.0])),
            (150, spec([10.0, 0.0, 1.0], [0.0, 0.0, 1.0])),
            (250, spec([0.0, 0.0, 1.0], [0.0, 5.0, 5.0])),
            (399, spec([0.0, 3.0, 1.0], [1.0, 5.0, 5.0])),
        ],
    )
}

#[test]
fn a_keyframed_path_passes_through_each_key_at_its_frame_bit_for_bit() {
    let a = hairpin();
    let CameraPath::Keyframes { keys } = &a.path else {
        unreachable!()
    };
    for key in keys {
        let got = a.camera(&base(), key.frame).unwrap();
        assert_eq!(bits(&got), bits(&key.camera), "frame {}", key.frame);
    }
}

#[test]
fn a_keyframed_path_never_leaves_its_segments_bounds() {
    let a = hairpin();
    let CameraPath::Keyframes { keys } = &a.path else {
        unreachable!()
    };
    let mut overshoots = 0;
    for (i, pair) in keys.windows(2).enumerate() {
        let (k1, k2) = (&pair[0], &pair[1]);
        for frame in k1.frame..=k2.frame {
            let got = a.camera(&base(), frame).unwrap();
            for (what, p, a, b) in [
                ("eye", got.eye, k1.camera.eye, k2.camera.eye),
                ("look_at", got.look_at, k1.camera.look_at, k2.camera.look_at),
            ] {
                let (lo, hi) = (a.min(b), a.max(b));
                assert!(
                    p.cmpge(lo).all() && p.cmple(hi).all(),
                    "frame {frame} {what} {p:?} outside {lo:?}..{hi:?}"
                );
            }
            // The spline itself, unclamped, does leave the bounds on this path.
            let u = f64::from(frame - k1.frame) / f64::from(k2.frame - k1.frame);
            let before = i.checked_sub(1).map(|j| keys[j].camera.eye);
            let after = keys.get(i + 2).map(|k| k.camera.eye);
            let free = unclamped_segment(before, k1.camera.eye, k2.camera.eye, after, u);
            let (lo, hi) = (
                k1.camera.eye.min(k2.camera.eye),
                k1.camera.eye.max(k2.camera.eye),
            );
            if !(free.cmpge(lo).all() && free.cmple(hi).all()) {
                overshoots += 1;
            }
        }
    }
    assert!(
        overshoots > 10,
        "only {overshoots} frames overshoot unclamped"
    );
    // Between keys the path moves: the second segment's middle is off the straight line.
    let mid = a.camera(&base(), 125).unwrap();
    assert!(mid.eye.z > 0.0 && mid.eye.z < 1.0, "{:?}", mid.eye);
}

#[test]
fn a_keyframed_path_holds_before_its_first_key_and_after_its_last() {
    let first = spec([1.0, 2.0, 3.0], [0.0, 0.0, 0.0]);
    let last = CameraSpec {
        up: DVec3::new(0.0, 2.0, 0.5),
        vfov_degrees: 60.0,
        ..spec([-1.0, 2.0, 3.0], [0.5, 0.0, 0.0])
    };
    let a = keyed(20, &[(5, first), (10, last)]);
    for frame in 0..=5 {
        assert_eq!(bits(&a.camera(&base(), frame).unwrap()), bits(&first));
    }
    for frame in 10..20 {
        assert_eq!(bits(&a.camera(&base(), frame).unwrap()), bits(&last));
    }
    // In between: up is interpolated and normalised, vfov linearly.
    let mid = a.camera(&base(), 7).unwrap();
    let up = DVec3::Y.lerp(DVec3::new(0.0, 2.0, 0.5), 0.4);
    assert!((mid.up - up.normalize()).length() < 1e-15, "{:?}", mid.up);
    assert_eq!(mid.vfov_degrees, 45.0 + 15.0 * 0.4);
    // A single key holds throughout.
    let one = keyed(3, &[(1, first)]);
    for frame in 0..3 {
        assert_eq!(bits(&one.camera(&base(), frame).unwrap()), bits(&first));
    }
}

/// Keys at the same position (here every eye but one) make the spline's knots coincide: the
/// segment is then straight, and a position that does not move stays exactly where it is.
#[test]
fn coincident_keys_give_a_straight_segment() {
    let a = keyed(
        40,
        &[
            (0, spec([1.0, 1.0, 1.0], [0.0, 0.0, 0.0])),
            (10, spec([1.0, 1.0, 1.0], [0.0, 0.0, 0.0])),
            (20, spec([3.0, 1.0, 1.0], [0.0, 0.0, 0.0])),
            (30, spec([3.0, 1.0, 1.0], [0.0, 0.0, 0.0])),
        ],
    );
    for frame in 0..40 {
        let got = a.camera(&base(), frame).unwrap();
        assert!(got.eye.is_finite() && got.look_at.is_finite(), "{frame}");
        assert_eq!(got.look_at, DVec3::ZERO);
        if frame <= 10 {
            assert_eq!(got.eye, DVec3::ONE);
        }
    }
    let got = a.camera(&base(), 15).unwrap();
    assert_eq!(got.eye, DVec3::new(2.0, 1.0, 1.0));
}

#[test]
fn frames_outside_the_animation_and_cameras_without_a_view_are_errors() {
    let a = orbit(360.0, 12);
    assert_eq!(
        error(&a, &base(), 12),
        "frame 12 is outside the animation's 12 frames (0 to 11)"
    );
    assert_eq!(
        error(&orbit(10.0, 1), &base(), 1),
        "frame 1 is outside the animation's 1 frame (0 to 0)"
    );
    // Up along +x is fine looking down -z, parallel to the view a quarter turn later.
    let sideways = CameraSpec {
        up: DVec3::X,
        ..spec([0.0, 0.0, 5.0], [0.0, 0.0, 0.0])
    };
    assert!(a.camera(&sideways, 0).is_ok());
    assert_eq!(
        error(&orbit(360.0, 4), &sideways, 1),
        "animation frame 1: up is parallel to the view direction (or zero)"
    );
    // Opposite ups cancel halfway.
    let down = CameraSpec {
        up: DVec3::NEG_Y,
        ..spec([0.0, 0.0, 5.0], [0.0, 0.0, 0.0])
    };
    let flip = keyed(11, &[(0, spec([0.0, 0.0, 5.0], [0.0; 3])), (10, down)]);
    assert!(flip.camera(&base(), 4).is_ok());
    assert_eq!(
        error(&flip, &base(), 5),
        "animation frame 5: up is parallel to the view direction (or zero)"
    );
    // The target moving through a still eye (a straight segment: its first two keys coincide).
    let through = keyed(
        4,
        &[
            (0, spec([0.0, 0.0, 1.0], [0.0, 0.0, 0.0])),
            (1, spec([0.0, 0.0, 1.0], [0.0, 0.0, 0.0])),
            (3, spec([0.0, 0.0, 1.0], [0.0, 0.0, 2.0])),
        ],
    );
    assert_eq!(
        error(&through, &base(), 2),
        "animation frame 2: eye and look_at are the same point"
    );
    // A finite turn whose angle overflows at a later frame.
    assert_eq!(
        error(&orbit(f64::MAX, 4), &sideways, 2),
        "animation frame 2: the camera's position is not finite"
    );
    // An invalid animation is an error at every frame.
    assert_eq!(
        error(&orbit(f64::NAN, 12), &base(), 0),
        "animation orbit degrees: NaN is not a finite number"
    );
}

#[test]
fn each_invalid_animation_has_its_own_message() {
    assert_eq!(
        invalid(&orbit(90.0, 0)),
        "animation frames: 0 is not between 1 and 100000"
    );
    assert_eq!(
        invalid(&orbit(90.0, MAX_FRAMES + 1)),
        "animation frames: 100001 is not between 1 and 100000"
    );
    assert!(orbit(90.0, MAX_FRAMES).validate().is_ok());
    assert_eq!(
        invalid(&orbit(f64::INFINITY, 10)),
        "animation orbit degrees: inf is not a finite number"
    );
    assert_eq!(
        invalid(&keyed(10, &[])),
        "animation lists no keyframes (at least one is needed)"
    );
    let good = spec([0.0, 0.0, 5.0], [0.0, 0.0, 0.0]);
    let with = |key: CameraSpec| invalid(&keyed(30, &[(0, good), (10, good), (24, key)]));
    assert_eq!(
        invalid(&keyed(30, &[(0, good), (24, good), (24, good)])),
        "animation keyframe 2 (frame 24): frames must increase strictly, but keyframe 1 is at \
         frame 24"
    );
    assert_eq!(
        invalid(&keyed(30, &[(10, good), (5, good)])),
        "animation keyframe 1 (frame 5): frames must increase strictly, but keyframe 0 is at \
         frame 10"
    );
    assert_eq!(
        invalid(&keyed(24, &[(0, good), (10, good), (24, good)])),
        "animation keyframe 2 (frame 24): frame 24 is outside the animation's 24 frames (0 to 23)"
    );
    assert_eq!(
        with(spec([1.0, 2.0, 3.0], [1.0, 2.0, 3.0])),
        "animation keyframe 2 (frame 24): eye and look_at are the same point"
    );
    assert_eq!(
        with(CameraSpec {
            up: DVec3::new(0.0, 0.0, -2.0),
            ..good
        }),
        "animation keyframe 2 (frame 24): up is parallel to the view direction (or zero)"
    );
    assert_eq!(
        with(CameraSpec {
            up: DVec3::ZERO,
            ..good
        }),
        "animation keyframe 2 (frame 24): up is parallel to the view direction (or zero)"
    );
    for (field, key) in [
        ("eye", spec([f64::NAN, 0.0, 0.0], [0.0; 3])),
        ("look_at", spec([0.0; 3], [0.0, f64::INFINITY, 0.0])),
        (
            "up",
            CameraSpec {
                up: DVec3::new(0.0, 1.0, f64::NEG_INFINITY),
                ..good
            },
        ),
    ] {
        assert_eq!(
            with(key),
            format!("animation keyframe 2 (frame 24): {field} must be finite numbers")
        );
    }
    for (vfov, shown) in [(0.0, "0"), (180.0, "180"), (-5.0, "-5"), (f64::NAN, "NaN")] {
        assert_eq!(
            with(CameraSpec {
                vfov_degrees: vfov,
                ..good
            }),
            format!(
                "animation keyframe 2 (frame 24): vfov {shown} is not between 0 and 180 degrees"
            )
        );
    }
    assert!(
        keyed(30, &[(0, good), (10, good), (29, good)])
            .validate()
            .is_ok()
    );
}

const TRIANGLE: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";

/// The manifest `json` beside a one-triangle `t.obj` in a scratch folder, loaded.
fn load_manifest(json: &str) -> (Result<crate::scene::Scene, String>, PathBuf) {
    let dir = crate::scratch::Scratch::new("hort-animation-tests-");
    std::fs::write(dir.join("t.obj"), TRIANGLE).unwrap();
    let p = dir.join("s.json");
    std::fs::write(&p, json).unwrap();
    (load_scene(&p).map_err(|e| e.to_string()), p)
}

fn manifest_error(json: &str) -> String {
    let (scene, p) = load_manifest(json);
    let e = scene.expect_err("must fail");
    let prefix = format!("{}: ", p.display());
    e.strip_prefix(&prefix)
        .unwrap_or_else(|| panic!("{e} does not start with {prefix}"))
        .to_string()
}

/// A manifest's keyframes are in world coordinates: they move into the scene's local frame
/// (origin at the triangle's centre, (0.5, 0.5, 0)) as its camera does; up and vfov default.
#[test]
fn a_manifest_animation_loads_into_the_local_frame() {
    let (scene, _) = load_manifest(
        r#"{"meshes": ["t.obj"], "camera": {"eye": [0.5, 0.5, 9], "look_at": [0.5, 0.5, 0]},
            "animation": {"frames": 48, "keyframes": [
              {"frame": 0, "eye": [0.5, 0.5, 5], "look_at": [0.5, 0.5, 0]},
              {"frame": 24, "eye": [5.5, 0.5, 0], "look_at": [0.5, 1.5, 0], "up": [0, 0, 2],
               "vfov": 30}]}}"#,
    );
    let scene = scene.unwrap();
    assert_eq!(scene.camera.eye, DVec3::new(0.0, 0.0, 9.0));
    let expected = keyed(
        48,
        &[
            (0, spec([0.0, 0.0, 5.0], [0.0; 3])),
            (
                24,
                CameraSpec {
                    up: DVec3::new(0.0, 0.0, 2.0),
                    vfov_degrees: 30.0,
                    ..spec([5.0, 0.0, 0.0], [0.0, 1.0, 0.0])
                },
            ),
        ],
    );
    let animation = scene.animation.clone().expect("an animation");
    assert_eq!(animation, expected);
    let base = scene.camera_for(64, 48);
    assert_eq!(
        bits(&animation.camera(&base, 47).unwrap()),
        bits(&animation.camera(&base, 24).unwrap())
    );
    // A manifest without one has none.
    let (scene, _) = load_manifest(r#"{"meshes": ["t.obj"]}"#);
    assert_eq!(scene.unwrap().animation, None);
}

#[test]
fn a_malformed_manifest_animation_names_the_keyframe() {
    let key = |frame: u32, eye: &str| {
        format!(r#"{{"frame": {frame}, "eye": {eye}, "look_at": [0.5, 0.5, 0]}}"#)
    };
    let manifest = |frames: u32, keys: &[String]| {
        format!(
            r#"{{"meshes": ["t.obj"], "animation": {{"frames": {frames}, "keyframes": [{}]}}}}"#,
            keys.join(", ")
        )
    };
    let good = |frame| key(frame, "[0.5, 0.5, 5]");
    assert_eq!(
        manifest_error(&manifest(
            48,
            &[good(0), good(12), key(24, "[0.5, 0.5, 0]")]
        )),
        "manifest field `animation.keyframes[2]`: eye and look_at are the same point"
    );
    assert_eq!(
        manifest_error(&manifest(48, &[good(0), good(12), good(12)])),
        "manifest field `animation.keyframes[2]`: frames must increase strictly, but keyframe 1 \
         is at frame 12"
    );
    assert_eq!(
        manifest_error(&manifest(48, &[good(0), good(48)])),
        "manifest field `animation.keyframes[1]`: frame 48 is outside the animation's 48 frames \
         (0 to 47)"
    );
    assert_eq!(
        manifest_error(&manifest(0, &[good(0)])),
        "manifest field `animation.frames`: 0 is not between 1 and 100000"
    );
    assert_eq!(
        manifest_error(&manifest(48, &[])),
        "manifest field `animation.keyframes`: lists no keyframes (at least one is needed)"
    );
    assert_eq!(
        manifest_error(&manifest(
            48,
            &[
                good(0),
                r#"{"frame": 5, "eye": [0,0,1], "look_at": [0,0,0], "vfov": 180}"#.into()
            ]
        )),
        "manifest field `animation.keyframes[1]`: vfov 180 is not between 0 and 180 degrees"
    );
    let e = manifest_error(&manifest(
        48,
        &[
            good(0),
            r#"{"frame": 5, "eye": [0,0,1], "look_at": [0,0,0], "fov": 30}"#.into(),
        ],
    ));
    assert!(
        e.starts_with("manifest field `animation.keyframes[1].fov`: unknown field `fov`"),
        "{e}"
    );
    let e = manifest_error(r#"{"meshes": ["t.obj"], "animation": {"frames": 4}}"#);
    assert!(
        e.starts_with("manifest field `animation`: missing field `keyframes`"),
        "{e}"
    );
}

#[test]
fn the_schema_shows_the_animation_field() {
    assert!(crate::scene::MANIFEST_SCHEMA.contains(r#""animation": {"frames": 48,"#));
}
