//! `hort render` of a textured scene whose texture file is missing: an error naming the file
//! and the material, or with `--missing-textures flat` a warning and the material's flat Kd
//! (the same image as without the `map_Kd`).

use crate::common;

use common::{hort, scene, scratch, stderr};
use std::path::Path;

/// The globe scene copied into `dir` without `globe.png`, with its library as `mtl`.
fn globe_without_its_map(dir: &Path, mtl: &str) -> std::path::PathBuf {
    for file in ["globe.json", "globe.obj", "tiles.png"] {
        std::fs::copy(scene("globe").join(file), dir.join(file)).unwrap();
    }
    std::fs::write(dir.join("globe.mtl"), mtl).unwrap();
    dir.join("globe.json")
}

const MTL: &str =
    "newmtl globe\nKd 1 1 1\nmap_Kd globe.png\nnewmtl floor\nKd 0.9 0.9 0.9\nmap_Kd tiles.png\n";

fn render(scene: &Path, out: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "render",
        scene.to_str().unwrap(),
        "--monolithic",
        "--width",
        "32",
        "--height",
        "24",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    hort(&args)
}

#[test]
fn a_missing_texture_is_an_error_or_with_the_flag_the_flat_colour() {
    let dir = scratch("missing-texture");
    let json = globe_without_its_map(&dir, MTL);
    let mtl = dir.join("globe.mtl");
    let missing = dir.join("globe.png");
    let what = format!(
        "{}: texture of {}:3 material \"globe\": the file does not exist",
        missing.display(),
        mtl.display()
    );

    let refused = render(&json, &dir.join("a.pfm"), &[]);
    assert!(!refused.status.success());
    assert_eq!(stderr(&refused).trim_end(), format!("error: {what}"));
    assert!(!dir.join("a.pfm").exists(), "nothing is written");

    let flat = render(
        &json,
        &dir.join("flat.pfm"),
        &["--missing-textures", "flat"],
    );
    assert!(flat.status.success(), "{}", stderr(&flat));
    let warning = format!(
        "warning: {what}; the surface shows its flat Kd colour instead (--missing-textures flat)"
    );
    assert!(
        stderr(&flat).lines().any(|l| l == warning),
        "{}",
        stderr(&flat)
    );

    // The flat colour is exactly the scene without that map_Kd.
    let plain = scratch("missing-texture-plain");
    let json = globe_without_its_map(&plain, &MTL.replace("map_Kd globe.png\n", ""));
    let o = render(&json, &plain.join("plain.pfm"), &[]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(
        std::fs::read(dir.join("flat.pfm")).unwrap(),
        std::fs::read(plain.join("plain.pfm")).unwrap()
    );
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&plain);
}
