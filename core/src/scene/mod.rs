//! Scene input: triangle meshes from OBJ/MTL, an optional JSON manifest, and the documented
//! defaults (framing camera, one point light) for whatever the manifest leaves out.
//!
//! Triangle order, which the hit buffer exposes, is: meshes in manifest order, then faces in
//! file order, polygons fan-triangulated `(0, i, i + 1)` in place.

mod binary;
pub mod files;
mod framing;
mod manifest;
mod mesh;
mod mtl;
mod obj;
mod ranged;
mod world;

pub use binary::{
    SCENE_BINARY_HEADER_LEN, SCENE_BINARY_MAGIC, SCENE_BINARY_VERSION, SceneBinaryError,
    decode_scene, encode_scene, encode_scene_named,
};
pub use framing::{default_camera, default_light, framed_camera, scene_bounds};
pub use manifest::{MANIFEST_SCHEMA, Manifest, ManifestAnimation, animation_from, parse_manifest};
pub use mesh::{Material, Mesh, NO_NORMAL, NO_TEXCOORD, TriangleShading};
pub use mtl::diffuse_map_files;
pub use obj::{
    ObjRange, ObjScan, RangeFaces, TextureFallback, parse_obj, parse_obj_range, scan_obj,
};
pub use ranged::{
    override_materials, scene_image_settings, scene_mesh_files, scene_of_manifest_without_geometry,
    scene_without_geometry,
};

use crate::animation::Animation;
use crate::error::SceneError;
use glam::DVec3;
use std::path::{Path, PathBuf};

/// Largest accepted image width or height, in pixels.
pub const MAX_IMAGE_SIDE: u32 = 65_536;
/// Largest accepted pixel count (width x height): 2^27, about 134 megapixels.
pub const MAX_PIXELS: u64 = 1 << 27;
/// Largest accepted samples per pixel.
pub const MAX_SPP: u32 = 65_536;
/// Largest accepted total sample count (pixels x spp): 2^34.
pub const MAX_SAMPLES: u64 = 1 << 34;

/// Default image size and sampling when neither flags nor manifest give them.
pub const DEFAULT_WIDTH: u32 = 960;
/// See [`DEFAULT_WIDTH`].
pub const DEFAULT_HEIGHT: u32 = 540;

/// A pinhole camera: eye, target, up and vertical field of view in degrees.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CameraSpec {
    /// The eye position, world units.
    pub eye: DVec3,
    /// The point the camera looks at; differs from `eye`.
    pub look_at: DVec3,
    /// The up direction; not parallel to the view direction.
    pub up: DVec3,
    /// The vertical field of view in degrees, in (0, 180).
    pub vfov_degrees: f64,
}

/// A light source. Radiometry: Lambertian surfaces reflect `kd / pi * E`, where the irradiance
/// `E` is `intensity * cos / r^2` for a point light and `irradiance * cos` for a directional one.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(tag = "kind", rename_all = "lowercase")]
pub enum Light {
    /// An isotropic point light with radiant intensity in W/sr per RGB channel.
    Point {
        /// The light's position, world units.
        position: DVec3,
        /// Radiant intensity, W/sr per RGB channel.
        intensity: [f32; 3],
    },
    /// A light at infinity; `direction` is the way its light travels (unit length), `irradiance`
    /// is the irradiance on a surface facing it, per RGB channel.
    Directional {
        /// The direction the light travels, unit length.
        direction: DVec3,
        /// Irradiance on a surface facing the light, per RGB channel.
        irradiance: [f32; 3],
    },
}

/// Image settings a manifest may fix; flags override them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ImageSettings {
    /// Image width in pixels.
    pub width: Option<u32>,
    /// Image height in pixels.
    pub height: Option<u32>,
    /// Samples per pixel.
    pub spp: Option<u32>,
}

/// A loaded scene: geometry plus everything needed to light and view it.
///
/// Everything positional (mesh, camera, lights, framed bounds) is in the scene's local frame,
/// whose origin is [`Scene::origin`] in the files' world coordinates: a point at `p` in the
/// files is at `p - origin` here. Directions and distances are the same in both frames.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The file the scene came from (OBJ or manifest), for messages.
    pub source: PathBuf,
    /// Where the local frame's origin lies in world coordinates: the centre of the bounding box
    /// of the vertices used by triangles, computed in double precision from the files.
    pub origin: DVec3,
    /// Every triangle of the scene, in scene order, positions relative to `origin` (each the
    /// f64 offset rounded once to f32).
    pub mesh: Mesh,
    /// The camera as loaded, in the local frame. Render through [`Scene::camera_for`], which adapts an automatic
    /// camera to the image's aspect ratio.
    pub camera: CameraSpec,
    /// The bounds (min, max) that `camera` frames when it is the automatic camera (no manifest
    /// camera); `None` for a manifest camera.
    pub framed_bounds: Option<(DVec3, DVec3)>,
    /// The lights (possibly none); point lights in the local frame.
    pub lights: Vec<Light>,
    /// Constant ambient radiance factor per channel: adds `kd * ambient` to every hit.
    pub ambient: [f32; 3],
    /// Radiance of rays that hit nothing.
    pub background: [f32; 3],
    /// Image settings the manifest fixed.
    pub image: ImageSettings,
    /// Things that were accepted but deserve a look (unknown material, missing MTL file, MTL
    /// features that are not rendered, unknown OBJ statements, no light), each naming its file.
    pub warnings: Vec<String>,
    /// The manifest's camera animation (keyframes in the local frame, checked), if it has one;
    /// `None` for an OBJ file. Not stored in the binary scene format: a decoded scene has none.
    pub animation: Option<Animation>,
}

impl Scene {
    /// The camera for a `width` x `height` image. A manifest camera is used as given. The
    /// automatic camera is [`framed_camera`] of the scene bounds: the same as `camera` for
    /// landscape and square images, moved back for portrait images so the whole bounding sphere
    /// stays in the picture (docs/ARCHITECTURE.md, "Default scene"). If `camera` was replaced
    /// after loading, it is used as given.
    pub fn camera_for(&self, width: u32, height: u32) -> CameraSpec {
        match self.framed_bounds {
            Some((lo, hi)) if self.camera == default_camera(lo, hi) => {
                framed_camera(lo, hi, width, height)
            }
            _ => self.camera,
        }
    }
}

/// Loads a scene from an OBJ file or a JSON manifest (chosen by the `.json` extension).
/// Coordinates are read in double precision and the scene is moved into its local frame (see
/// [`Scene`]), so its f32 geometry does not depend on where it sits in the world.
pub fn load_scene(path: &Path) -> Result<Scene, SceneError> {
    load_scene_with(path, TextureFallback::Error)
}

/// Whether `path` names a JSON scene manifest (`.json`, any case), else an OBJ file.
pub fn is_manifest(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"))
}

/// [`load_scene`] with a choice of what a texture that cannot be used does.
pub fn load_scene_with(path: &Path, fallback: TextureFallback) -> Result<Scene, SceneError> {
    if is_manifest(path) {
        manifest::load_manifest_scene(path, fallback)
    } else {
        load_obj_scene(path, fallback)
    }
}

/// Loads a bare OBJ file and frames it with the documented defaults.
fn load_obj_scene(path: &Path, fallback: TextureFallback) -> Result<Scene, SceneError> {
    let mut warnings = Vec::new();
    let (mesh, origin) = obj::load_obj(path, &mut warnings, fallback)?.localise(path)?;
    let bounds = scene_bounds(&mesh, path)?;
    let mut scene = scene_without_geometry(path, origin, bounds, warnings)?;
    scene.mesh = mesh;
    Ok(scene)
}

/// Checks image dimensions and sample count against the documented limits.
pub fn check_image_size(width: u32, height: u32, spp: u32) -> Result<(), SceneError> {
    let side = |what, v: u32| {
        if v == 0 || v > MAX_IMAGE_SIDE {
            Err(SceneError::OutOfRange {
                what,
                value: v.to_string(),
                limit: format!("must be 1 to {MAX_IMAGE_SIDE}"),
            })
        } else {
            Ok(())
        }
    };
    side("width", width)?;
    side("height", height)?;
    let pixels = u64::from(width) * u64::from(height);
    if pixels > MAX_PIXELS {
        return Err(SceneError::OutOfRange {
            what: "width x height",
            value: pixels.to_string(),
            limit: format!("at most {MAX_PIXELS} pixels"),
        });
    }
    if spp == 0 || spp > MAX_SPP {
        return Err(SceneError::OutOfRange {
            what: "spp",
            value: spp.to_string(),
            limit: format!("must be 1 to {MAX_SPP}"),
        });
    }
    let samples = pixels * u64::from(spp);
    if samples > MAX_SAMPLES {
        return Err(SceneError::OutOfRange {
            what: "width x height x spp",
            value: samples.to_string(),
            limit: format!("at most {MAX_SAMPLES} samples"),
        });
    }
    Ok(())
}

#[cfg(test)]
mod binary_tests;
#[cfg(test)]
mod tests;
#[cfg(test)]
mod wild_tests;
