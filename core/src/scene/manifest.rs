//! The JSON scene manifest: which OBJ files make the scene and how to view and light it.
//! Every field but `meshes` is optional; what is left out takes the documented default.

use super::framing::{default_camera, default_light, scene_bounds};
use super::mesh::Mesh;
use super::obj::TextureFallback;
use super::world::WorldMesh;
use super::{CameraSpec, ImageSettings, Light, MAX_IMAGE_SIDE, MAX_SPP, Scene, obj};
use crate::animation::{Animation, CameraKey, CameraPath, Problem, Where};
use crate::error::{SceneError, printable};
use glam::DVec3;
use serde::Deserialize;
use std::collections::BTreeMap;
use std::path::Path;

/// The manifest schema, for `--help` and the docs.
pub const MANIFEST_SCHEMA: &str = r#"{
  "meshes": ["ground.obj", "bunny.obj"],       // required; OBJ paths relative to the manifest
  "camera": {"eye": [x,y,z], "look_at": [x,y,z], "up": [0,1,0], "vfov": 45.0},
  "lights": [{"kind": "point", "position": [x,y,z], "intensity": [r,g,b] | n},
             {"kind": "directional", "direction": [x,y,z], "irradiance": [r,g,b] | n}],
  "ambient": n | [r,g,b],  "background": [r,g,b],
  "materials": {"mtl name or \"default\"": {"kd": [r,g,b]}},
  "width": 960, "height": 540, "spp": 1,
  "animation": {"frames": 48,                 // frames 0 to 47; keyframe frames increase
                "keyframes": [{"frame": 0, "eye": [x,y,z], "look_at": [x,y,z],
                               "up": [0,1,0], "vfov": 45.0}, ...]}
}"#;

/// A parsed manifest before its meshes are loaded.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// OBJ files relative to the manifest, in triangle numbering order; at least one.
    pub meshes: Vec<String>,
    /// The camera; automatic framing when absent.
    pub camera: Option<ManifestCamera>,
    /// The lights; the default light when absent, none when an empty list.
    pub lights: Option<Vec<ManifestLight>>,
    /// Constant ambient factor per channel (a number means grey); 0 when absent.
    pub ambient: Option<Rgb>,
    /// Linear radiance of rays that hit nothing; black when absent.
    pub background: Option<[f32; 3]>,
    /// Diffuse reflectance overrides by MTL material name (`default`: faces without one).
    #[serde(default)]
    pub materials: BTreeMap<String, ManifestMaterial>,
    /// Image width in pixels; flags override it.
    pub width: Option<u32>,
    /// Image height in pixels; flags override it.
    pub height: Option<u32>,
    /// Samples per pixel; flags override it.
    pub spp: Option<u32>,
    /// A keyframed camera path over the frames of an animation; none when absent.
    pub animation: Option<ManifestAnimation>,
}

/// An animation: its frame count and camera keyframes (world coordinates, as `camera`).
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ManifestAnimation {
    /// Frames in the animation, 1 to [`crate::animation::MAX_FRAMES`].
    pub frames: u32,
    /// The keyframes, frames increasing strictly; at least one.
    pub keyframes: Vec<ManifestKeyframe>,
}

/// A camera keyframe: the camera fields (same defaults) at frame `frame`.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ManifestKeyframe {
    /// The frame the key holds at.
    pub frame: u32,
    /// The eye, world units.
    pub eye: [f64; 3],
    /// The target, world units.
    pub look_at: [f64; 3],
    /// The up direction (default +y).
    pub up: Option<[f64; 3]>,
    /// The vertical field of view, degrees (default 45).
    pub vfov: Option<f64>,
}

/// Camera fields; `up` defaults to +y and `vfov` (vertical, degrees) to 45.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ManifestCamera {
    pub eye: [f64; 3],
    pub look_at: [f64; 3],
    pub up: Option<[f64; 3]>,
    pub vfov: Option<f64>,
}

/// A light, tagged by `kind`.
#[derive(Debug, Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum ManifestLight {
    Point {
        position: [f64; 3],
        intensity: Rgb,
    },
    Directional {
        direction: [f64; 3],
        irradiance: Rgb,
    },
}

/// A colour given as one grey number or an `[r, g, b]` triple.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(untagged)]
pub enum Rgb {
    Grey(f32),
    Triple([f32; 3]),
}

impl Rgb {
    fn to_array(self) -> [f32; 3] {
        match self {
            Rgb::Grey(v) => [v; 3],
            Rgb::Triple(c) => c,
        }
    }
}

/// A material override.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ManifestMaterial {
    pub kd: [f32; 3],
}

/// Loads a manifest and the OBJ files it names.
pub(super) fn load_manifest_scene(
    path: &Path,
    fallback: TextureFallback,
) -> Result<Scene, SceneError> {
    let manifest = read_manifest(path)?;
    let base = path.parent().unwrap_or(Path::new("."));
    let mut warnings = Vec::new();
    let mut world = WorldMesh::default();
    for file in &manifest.meshes {
        world.append(obj::load_obj(&base.join(file), &mut warnings, fallback)?);
    }
    // The local frame (see `Scene`): the manifest's positions are moved by the same origin.
    let (mut mesh, origin) = world.localise(path)?;
    apply_material_overrides(&mut mesh, &manifest, path)?;
    let (lo, hi) = scene_bounds(&mesh, path)?;
    manifest_scene(path, &manifest, origin, (lo, hi), mesh, warnings)
}

/// The scene of `manifest` (read from `path`) around `mesh`, already in the local frame of
/// `origin` with bounds `lo, hi`: camera, lights, colours and image settings from the manifest
/// or the defaults, and the manifest's warnings added to `warnings`.
pub(super) fn manifest_scene(
    path: &Path,
    manifest: &Manifest,
    origin: DVec3,
    (lo, hi): (DVec3, DVec3),
    mesh: Mesh,
    mut warnings: Vec<String>,
) -> Result<Scene, SceneError> {
    let (camera, framed_bounds) = match &manifest.camera {
        Some(c) => (camera_from(c, origin, path)?, None),
        None => (default_camera(lo, hi), Some((lo, hi))),
    };
    let lights = match &manifest.lights {
        Some(list) => list
            .iter()
            .enumerate()
            .map(|(i, l)| light_from(l, i, origin, path))
            .collect::<Result<Vec<_>, _>>()?,
        None => vec![default_light(lo, hi)],
    };
    let animation = match &manifest.animation {
        Some(a) => Some(animation_from(a, origin, path)?),
        None => None,
    };
    let ambient = colour(manifest.ambient.map(Rgb::to_array), "ambient", path)?;
    let background = colour(manifest.background, "background", path)?;
    let image = image_settings(manifest, path)?;
    warn_bright_overrides(manifest, path, &mut warnings);
    if let Some(w) = unlit_warning(&lights, ambient, path) {
        warnings.push(w);
    }
    // Two meshes may share a material library: say each thing once.
    let mut seen = std::collections::HashSet::new();
    warnings.retain(|w| seen.insert(w.clone()));
    Ok(Scene {
        source: path.to_path_buf(),
        origin,
        mesh,
        camera,
        framed_bounds,
        lights,
        ambient,
        background,
        image,
        warnings,
        animation,
    })
}

/// Reads and parses the manifest at `path`; one that lists no meshes is an error.
pub(super) fn read_manifest(path: &Path) -> Result<Manifest, SceneError> {
    let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let manifest = parse_manifest(&text, path)?;
    if manifest.meshes.is_empty() {
        return Err(SceneError::Manifest {
            path: path.to_path_buf(),
            field: "meshes".into(),
            detail: "lists no OBJ files".into(),
        });
    }
    Ok(manifest)
}

/// Parses manifest JSON; errors carry the JSON path of the offending field.
/// Text after the JSON object (`{...} trailing`) is an error too, at the root.
pub fn parse_manifest(text: &str, path: &Path) -> Result<Manifest, SceneError> {
    let de = &mut serde_json::Deserializer::from_str(text);
    let manifest = serde_path_to_error::deserialize(&mut *de).map_err(|e| {
        let field = printable(&e.path().to_string());
        SceneError::Manifest {
            path: path.to_path_buf(),
            field: if field == "." || field == "?" {
                "(root)".into()
            } else {
                field
            },
            detail: printable(&e.into_inner().to_string()),
        }
    })?;
    de.end().map_err(|e| SceneError::Manifest {
        path: path.to_path_buf(),
        field: "(root)".into(),
        detail: e.to_string(),
    })?;
    Ok(manifest)
}

pub(super) fn apply_material_overrides(
    mesh: &mut Mesh,
    manifest: &Manifest,
    path: &Path,
) -> Result<(), SceneError> {
    for (name, m) in &manifest.materials {
        let shown = printable(name);
        let field = format!("materials.{shown}.kd");
        if m.kd.iter().any(|c| !c.is_finite() || *c < 0.0) {
            return Err(SceneError::Manifest {
                path: path.to_path_buf(),
                field,
                detail: "must be finite and non-negative".into(),
            });
        }
        let mut found = false;
        for mat in mesh.materials.iter_mut().filter(|mat| &mat.name == name) {
            mat.kd = m.kd;
            found = true;
        }
        if !found {
            return Err(SceneError::Manifest {
                path: path.to_path_buf(),
                field: format!("materials.{shown}"),
                detail: "no mesh uses a material of that name".into(),
            });
        }
    }
    Ok(())
}

/// One warning for the manifest's material overrides whose `kd` exceeds 1 (more light out than
/// in: not physically plausible). They are rendered as given.
fn warn_bright_overrides(manifest: &Manifest, path: &Path, warnings: &mut Vec<String>) {
    let mut bright = manifest
        .materials
        .iter()
        .filter(|(_, m)| m.kd.iter().any(|&c| c > 1.0));
    let Some((name, first)) = bright.next() else {
        return;
    };
    let more = bright.count();
    let name = printable(name);
    let [r, g, b] = first.kd;
    let others = match more {
        0 => String::new(),
        1 => " (and 1 more material)".to_string(),
        n => format!(" (and {n} more materials)"),
    };
    warnings.push(format!(
        "{}: manifest field `materials.{name}.kd` is [{r}, {g}, {b}]{others}: a diffuse colour \
         above 1 reflects more light than it receives, which is not physically plausible; it is \
         rendered as given (use values from 0 to 1)",
        path.display()
    ));
}

/// The warning for a manifest whose lights cannot light anything (none, or all of zero
/// strength) when there is no ambient light either: the image will be black.
fn unlit_warning(lights: &[Light], ambient: [f32; 3], path: &Path) -> Option<String> {
    let lit = lights.iter().any(|l| match l {
        Light::Point { intensity, .. } => intensity.iter().any(|&c| c > 0.0),
        Light::Directional { irradiance, .. } => irradiance.iter().any(|&c| c > 0.0),
    });
    if lit || ambient.iter().any(|&c| c > 0.0) {
        return None;
    }
    let what = if lights.is_empty() {
        "manifest field `lights` is an empty list"
    } else {
        "every light in manifest field `lights` has zero intensity or irradiance"
    };
    Some(format!(
        "{}: {what} and `ambient` is 0, so nothing is lit and the image will be black (only the \
         background shows); leave `lights` out to get the default light, or add one, e.g. \
         \"lights\": [{{\"kind\": \"point\", \"position\": [x, y, z], \"intensity\": 100}}]",
        path.display()
    ))
}

fn finite_vec(v: [f64; 3], field: &str, path: &Path) -> Result<DVec3, SceneError> {
    if v.iter().all(|c| c.is_finite()) {
        Ok(DVec3::from(v))
    } else {
        Err(SceneError::Manifest {
            path: path.to_path_buf(),
            field: field.to_string(),
            detail: "must be finite numbers".into(),
        })
    }
}

/// The manifest camera, moved into the local frame whose origin is `origin`.
fn camera_from(c: &ManifestCamera, origin: DVec3, path: &Path) -> Result<CameraSpec, SceneError> {
    let vfov = c.vfov.unwrap_or(45.0);
    if !(vfov > 0.0 && vfov < 180.0) {
        return Err(SceneError::Manifest {
            path: path.to_path_buf(),
            field: "camera.vfov".into(),
            detail: format!("{vfov} is not between 0 and 180 degrees"),
        });
    }
    Ok(CameraSpec {
        eye: finite_vec(c.eye, "camera.eye", path)? - origin,
        look_at: finite_vec(c.look_at, "camera.look_at", path)? - origin,
        up: finite_vec(c.up.unwrap_or([0.0, 1.0, 0.0]), "camera.up", path)?,
        vfov_degrees: vfov,
    })
}

/// The manifest animation, its keyframes moved into the local frame whose origin is `origin`
/// (as [`camera_from`] moves the camera) and checked ([`Animation::validate`]): an error names
/// the field, `animation.keyframes[2]` for a keyframe. Also how the HTTP API takes an
/// animation given in a request (`path` then names the request's scene).
pub fn animation_from(
    a: &ManifestAnimation,
    origin: DVec3,
    path: &Path,
) -> Result<Animation, SceneError> {
    let keys = a
        .keyframes
        .iter()
        .enumerate()
        .map(|(i, k)| {
            let field = |name: &str| format!("animation.keyframes[{i}].{name}");
            Ok(CameraKey {
                frame: k.frame,
                camera: CameraSpec {
                    eye: finite_vec(k.eye, &field("eye"), path)? - origin,
                    look_at: finite_vec(k.look_at, &field("look_at"), path)? - origin,
                    up: finite_vec(k.up.unwrap_or([0.0, 1.0, 0.0]), &field("up"), path)?,
                    vfov_degrees: k.vfov.unwrap_or(45.0),
                },
            })
        })
        .collect::<Result<Vec<_>, SceneError>>()?;
    let animation = Animation {
        frames: a.frames,
        path: CameraPath::Keyframes { keys },
    };
    match animation.problem() {
        None => Ok(animation),
        Some(Problem { at, detail }) => Err(SceneError::Manifest {
            path: path.to_path_buf(),
            field: match at {
                Where::Frames => "animation.frames".into(),
                Where::Keys | Where::Degrees => "animation.keyframes".into(),
                Where::Key { index, .. } => format!("animation.keyframes[{index}]"),
            },
            detail,
        }),
    }
}

/// The manifest light, moved into the local frame whose origin is `origin`.
fn light_from(
    l: &ManifestLight,
    i: usize,
    origin: DVec3,
    path: &Path,
) -> Result<Light, SceneError> {
    match l {
        ManifestLight::Point {
            position,
            intensity,
        } => Ok(Light::Point {
            position: finite_vec(*position, &format!("lights[{i}].position"), path)? - origin,
            intensity: colour(
                Some(intensity.to_array()),
                &format!("lights[{i}].intensity"),
                path,
            )?,
        }),
        ManifestLight::Directional {
            direction,
            irradiance,
        } => {
            let field = format!("lights[{i}].direction");
            let d = finite_vec(*direction, &field, path)?;
            if d.length() <= 0.0 {
                return Err(SceneError::Manifest {
                    path: path.to_path_buf(),
                    field,
                    detail: "must not be the zero vector".into(),
                });
            }
            Ok(Light::Directional {
                direction: d.normalize(),
                irradiance: colour(
                    Some(irradiance.to_array()),
                    &format!("lights[{i}].irradiance"),
                    path,
                )?,
            })
        }
    }
}

fn colour(c: Option<[f32; 3]>, field: &str, path: &Path) -> Result<[f32; 3], SceneError> {
    let c = c.unwrap_or([0.0; 3]);
    if c.iter().all(|v| v.is_finite() && *v >= 0.0) {
        Ok(c)
    } else {
        Err(SceneError::Manifest {
            path: path.to_path_buf(),
            field: field.to_string(),
            detail: "must be finite and non-negative".into(),
        })
    }
}

pub(super) fn image_settings(m: &Manifest, path: &Path) -> Result<ImageSettings, SceneError> {
    let check = |v: Option<u32>, field: &str, max: u32| match v {
        Some(x) if x == 0 || x > max => Err(SceneError::Manifest {
            path: path.to_path_buf(),
            field: field.to_string(),
            detail: format!("{x} is not between 1 and {max}"),
        }),
        _ => Ok(v),
    };
    Ok(ImageSettings {
        width: check(m.width, "width", MAX_IMAGE_SIDE)?,
        height: check(m.height, "height", MAX_IMAGE_SIDE)?,
        spp: check(m.spp, "spp", MAX_SPP)?,
    })
}
