//! Which files make up a scene, and in what order they are found: the main file; if it is a
//! manifest (`.json`), the meshes it names, else the main file is the mesh; each mesh's
//! material libraries (its `mtllib` lines); each library's diffuse textures (`map_Kd`). Every
//! name is relative to the file that names it, and each file is taken once, in that order.
//!
//! One walk ([`walk_scene_files`]) serves every place that gathers a scene: the emulator's
//! client (local files), the HTTP API (files inline or in the bucket) and the Plan function
//! staging a scene given by key (S3 copies). Each reads and takes files its own way, through
//! a [`SceneFileSource`], and words its own errors.

use super::is_manifest;
use std::collections::BTreeSet;
use std::path::Path;

/// What a named file is to the scene.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SceneFileKind {
    /// An OBJ file a manifest names.
    Mesh,
    /// A material library an OBJ file names.
    Library,
    /// A diffuse texture a material library names.
    Texture,
}

impl SceneFileKind {
    /// The noun messages use: `mesh`, `material library`, `texture`.
    pub fn noun(self) -> &'static str {
        match self {
            SceneFileKind::Mesh => "mesh",
            SceneFileKind::Library => "material library",
            SceneFileKind::Texture => "texture",
        }
    }
}

/// Where [`walk_scene_files`] finds a scene's files and what it does with them ("takes": reads,
/// records, uploads or copies). Names given to it are relative to the scene's folder, except
/// the names as written in a file ([`SceneFileSource::check_name`]).
pub trait SceneFileSource {
    /// The error of a step.
    type Error;
    /// Takes the main file; an error if there is none.
    fn take_main(&mut self, main: &str) -> Result<(), Self::Error>;
    /// The meshes the manifest `main` (taken already) names, as written in it, in order.
    fn manifest_meshes(&mut self, main: &str) -> Result<Vec<String>, Self::Error>;
    /// Checks a name as written in the file `named_by` before it is resolved beside that file.
    fn check_name(
        &mut self,
        name: &str,
        kind: SceneFileKind,
        named_by: &str,
    ) -> Result<(), Self::Error>;
    /// Takes a mesh a manifest names; an error if there is none.
    fn take_mesh(&mut self, mesh: &str) -> Result<(), Self::Error>;
    /// The material libraries of the mesh `mesh` (taken already), as written on its `mtllib`
    /// lines, in order.
    fn mesh_libraries(&mut self, mesh: &str) -> Result<Vec<String>, Self::Error>;
    /// Takes a material library: the diffuse textures it names, as written, or `None` if there
    /// is no such library (the loader warns of it).
    fn take_library(&mut self, library: &str) -> Result<Option<Vec<String>>, Self::Error>;
    /// Takes a texture, if it exists (a missing one is the loader's error, naming it).
    fn take_texture(&mut self, texture: &str) -> Result<(), Self::Error>;
}

/// Walks the scene whose main file is `main` (relative to the scene's folder), handing
/// `source` each of its files once, in the order of the module documentation. A mesh named
/// twice, or a manifest naming itself, is read once.
pub fn walk_scene_files<S: SceneFileSource>(main: &str, source: &mut S) -> Result<(), S::Error> {
    source.take_main(main)?;
    let mut taken = BTreeSet::from([main.to_owned()]);
    let meshes = if is_manifest(Path::new(main)) {
        let mut meshes = Vec::new();
        for mesh in source.manifest_meshes(main)? {
            source.check_name(&mesh, SceneFileKind::Mesh, main)?;
            meshes.push(beside(main, &mesh));
        }
        meshes
    } else {
        vec![main.to_owned()]
    };
    let mut walked = BTreeSet::new();
    for mesh in meshes {
        if !walked.insert(mesh.clone()) {
            continue;
        }
        if taken.insert(mesh.clone()) {
            source.take_mesh(&mesh)?;
        }
        for library in source.mesh_libraries(&mesh)? {
            source.check_name(&library, SceneFileKind::Library, &mesh)?;
            let library = beside(&mesh, &library);
            if !taken.insert(library.clone()) {
                continue;
            }
            let Some(textures) = source.take_library(&library)? else {
                continue;
            };
            for texture in textures {
                source.check_name(&texture, SceneFileKind::Texture, &library)?;
                let texture = beside(&library, &texture);
                if taken.insert(texture.clone()) {
                    source.take_texture(&texture)?;
                }
            }
        }
    }
    Ok(())
}

/// `rel` relative to the folder of `file` (both relative to the scene's folder, `/` between
/// parts).
pub fn beside(file: &str, rel: &str) -> String {
    match file.rsplit_once('/') {
        Some((dir, _)) => format!("{dir}/{rel}"),
        None => rel.to_owned(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::BTreeMap;

    /// Files in memory; records what was taken, in order.
    struct Files {
        files: BTreeMap<&'static str, &'static str>,
        taken: Vec<String>,
    }

    impl Files {
        fn text(&self, name: &str) -> Result<&'static str, String> {
            self.files
                .get(name)
                .copied()
                .ok_or_else(|| format!("no {name}"))
        }

        fn words_after(&self, name: &str, keyword: &str) -> Vec<String> {
            let text = self.files.get(name).copied().unwrap_or_default();
            text.lines()
                .filter_map(|l| l.strip_prefix(keyword))
                .map(|w| w.trim().to_owned())
                .collect()
        }
    }

    impl SceneFileSource for Files {
        type Error = String;
        fn take_main(&mut self, main: &str) -> Result<(), String> {
            self.text(main)?;
            self.taken.push(main.to_owned());
            Ok(())
        }
        fn manifest_meshes(&mut self, main: &str) -> Result<Vec<String>, String> {
            Ok(self.words_after(main, "mesh "))
        }
        fn check_name(&mut self, name: &str, kind: SceneFileKind, by: &str) -> Result<(), String> {
            if name.starts_with('/') {
                return Err(format!("{by}: {} {name} is absolute", kind.noun()));
            }
            Ok(())
        }
        fn take_mesh(&mut self, mesh: &str) -> Result<(), String> {
            self.take_main(mesh)
        }
        fn mesh_libraries(&mut self, mesh: &str) -> Result<Vec<String>, String> {
            Ok(self.words_after(mesh, "mtllib "))
        }
        fn take_library(&mut self, library: &str) -> Result<Option<Vec<String>>, String> {
            if self.text(library).is_err() {
                return Ok(None);
            }
            self.taken.push(library.to_owned());
            Ok(Some(self.words_after(library, "map_Kd ")))
        }
        fn take_texture(&mut self, texture: &str) -> Result<(), String> {
            if self.text(texture).is_ok() {
                self.taken.push(texture.to_owned());
            }
            Ok(())
        }
    }

    fn walk(files: &[(&'static str, &'static str)], main: &str) -> Result<Vec<String>, String> {
        let mut source = Files {
            files: files.iter().copied().collect(),
            taken: Vec::new(),
        };
        walk_scene_files(main, &mut source).map(|()| source.taken)
    }

    #[test]
    fn files_are_taken_once_in_order_each_beside_the_file_naming_it() {
        let files = [
            ("s.json", "mesh m/a.obj\nmesh m/a.obj\nmesh b.obj"),
            ("m/a.obj", "mtllib a.mtl\nmtllib gone.mtl"),
            ("m/a.mtl", "map_Kd t/wood.png\nmap_Kd gone.png"),
            ("m/t/wood.png", ""),
            ("b.obj", "mtllib m/a.mtl\nmtllib b.mtl"),
            ("b.mtl", "map_Kd m/t/wood.png"),
        ];
        assert_eq!(
            walk(&files, "s.json").unwrap(),
            [
                "s.json",
                "m/a.obj",
                "m/a.mtl",
                "m/t/wood.png",
                "b.obj",
                "b.mtl"
            ]
        );
    }

    #[test]
    fn an_obj_main_file_is_its_own_mesh_and_its_libraries_are_taken() {
        let files = [
            ("a.obj", "mtllib a.mtl"),
            ("a.mtl", "map_Kd a.png"),
            ("a.png", ""),
        ];
        assert_eq!(walk(&files, "a.obj").unwrap(), ["a.obj", "a.mtl", "a.png"]);
    }

    #[test]
    fn a_missing_main_file_or_mesh_and_a_refused_name_stop_the_walk() {
        assert_eq!(walk(&[], "s.json").unwrap_err(), "no s.json");
        let files = [("s.json", "mesh a.obj")];
        assert_eq!(walk(&files, "s.json").unwrap_err(), "no a.obj");
        let files = [("s.json", "mesh a.obj"), ("a.obj", "mtllib /etc/a.mtl")];
        assert_eq!(
            walk(&files, "s.json").unwrap_err(),
            "a.obj: material library /etc/a.mtl is absolute"
        );
    }

    #[test]
    fn names_resolve_beside_their_file() {
        assert_eq!(beside("a.obj", "a.mtl"), "a.mtl");
        assert_eq!(beside("m/n/a.obj", "t/a.png"), "m/n/t/a.png");
        assert!(is_manifest(Path::new("x/S.JSON")));
        assert!(!is_manifest(Path::new("x.json.obj")));
    }
}
