//! The SCENE argument the timing examples share (included with `#[path]`; not an example
//! itself): a scene file, or `generated:N`, the scene `hort scene generate --triangles N --seed
//! 1` writes (generated into a temporary file, deleted after loading).

use hort_core::generate::generate_scene;
use hort_core::scene::{Scene, load_scene};
use std::path::PathBuf;

/// Loads the scene `arg` names (see the module documentation); panics with the reason if it
/// cannot.
pub fn load_scene_arg(arg: &str) -> Scene {
    let Some(n) = arg.strip_prefix("generated:") else {
        return load_scene(&PathBuf::from(arg)).expect("the scene loads");
    };
    let n: u64 = n.parse().expect("generated:N takes a triangle count");
    let path = std::env::temp_dir().join(format!("timing-example-{}-{n}.obj", std::process::id()));
    let mut file = std::io::BufWriter::new(std::fs::File::create(&path).expect("temp file"));
    generate_scene(n, 1, &mut file).expect("the scene generates");
    drop(file);
    let scene = load_scene(&path).expect("the scene loads");
    std::fs::remove_file(&path).expect("temp file removed");
    scene
}
