//! A scene given by key (`JobRequest::scene_key`), staged into its job: the Plan function copies
//! the main file, the meshes a manifest names, the material libraries the meshes name and the
//! textures those name (the walk of `hort_core::scene::files`) from beside the key into
//! `jobs/{job}/scene/`, inside the store (CopyObject). The function itself
//! reads only a manifest and each OBJ file once, in chunks, for its `mtllib` lines. From there
//! on the job is like any other whose files were uploaded: its later tasks (a Worker rebuilding
//! a lost split, a rerun) read the job's own copy, whatever happens to the key; a retried Plan
//! attempt copies again.
//!
//! The HTTP API checked that the main file and the meshes existed when it accepted the job;
//! they are checked again here (the bucket may have changed), with the same messages.

use super::HandlerError;
use super::events::JobRequest;
use crate::api::check_relative;
use hort_core::ids::JobId;
use hort_core::keys::scene_prefix;
use hort_core::scene::files::{SceneFileKind, SceneFileSource, walk_scene_files};
use hort_core::scene::{diffuse_map_files, is_manifest, parse_manifest};
use hort_core::store::{BlobStore, COPY_MAX_BYTES, StoreError};
use std::path::Path;

/// The largest manifest read, bytes: a manifest is a few KiB of JSON.
pub const MAX_MANIFEST_BYTES: u64 = 1 << 20;

/// Bytes of an OBJ file read at once while looking for its material libraries.
const SCAN_CHUNK_BYTES: u64 = 16 << 20;

/// Bytes of a material library read for the textures it names (libraries are small; a texture
/// named past this is not copied, and the loader then names it as missing).
const MAX_LIBRARY_BYTES: u64 = 4 << 20;

/// Copies the scene of `request.scene_key` into `jobs/{job}/scene/`; nothing for a job whose
/// scene was uploaded.
pub(super) fn stage_in(
    store: &dyn BlobStore,
    job: &JobId,
    request: &JobRequest,
) -> Result<(), HandlerError> {
    let Some(key) = &request.scene_key else {
        return Ok(());
    };
    let (folder, main) = match key.rsplit_once('/') {
        Some((folder, main)) => (format!("{folder}/"), main.to_owned()),
        None => (String::new(), key.clone()),
    };
    let mut staging = Staging {
        store,
        key,
        folder: &folder,
        target: scene_prefix(job),
        sizes: std::collections::BTreeMap::new(),
        main: None,
    };
    walk_scene_files(&main, &mut staging)?;
    staging.copy_main()
}

/// [`stage_in`]'s side of the scene walk: each file copied from beside the key into the job.
struct Staging<'a> {
    store: &'a dyn BlobStore,
    /// The scene's key (the main file's).
    key: &'a str,
    /// The key's folder, with its `/` (empty for a key at the bucket's top).
    folder: &'a str,
    /// `jobs/{job}/scene/`.
    target: String,
    /// The sizes of the files copied, by name.
    sizes: std::collections::BTreeMap<String, u64>,
    /// The main file and its size, until it is copied: after a manifest's mesh names are
    /// checked, before the first mesh (nothing is copied for a manifest that is refused).
    main: Option<(String, u64)>,
}

impl Staging<'_> {
    /// The key of the scene's file `name`.
    fn source(&self, name: &str) -> String {
        format!("{}{name}", self.folder)
    }

    /// The size of the scene's file `name`, `None` if there is no such object.
    fn size(&self, name: &str) -> Result<Option<u64>, HandlerError> {
        match self.store.size(&self.source(name)) {
            Ok(size) => Ok(Some(size)),
            Err(StoreError::NotFound { .. }) => Ok(None),
            Err(e) => Err(e.into()),
        }
    }

    /// Copies the main file, if it is not copied yet.
    fn copy_main(&mut self) -> Result<(), HandlerError> {
        match self.main.take() {
            Some((main, bytes)) => self.copy(&main, bytes),
            None => Ok(()),
        }
    }

    /// Copies the scene's file `name` of `bytes` bytes into the job.
    fn copy(&mut self, name: &str, bytes: u64) -> Result<(), HandlerError> {
        if bytes > COPY_MAX_BYTES {
            return Err(HandlerError::bad_input(format!(
                "{}: {bytes} bytes, over the {COPY_MAX_BYTES} bytes S3 copies in one request; \
                 split the mesh into files of at most 5 GiB and list them in a manifest",
                self.source(name)
            )));
        }
        self.store
            .copy(&self.source(name), &format!("{}{name}", self.target))?;
        self.sizes.insert(name.to_owned(), bytes);
        Ok(())
    }
}

impl SceneFileSource for Staging<'_> {
    type Error = HandlerError;

    fn take_main(&mut self, main: &str) -> Result<(), HandlerError> {
        let Some(bytes) = self.size(main)? else {
            return Err(HandlerError::bad_input(format!(
                "scene.key: there is no object {} in the bucket",
                self.key
            )));
        };
        if is_manifest(Path::new(main)) && bytes > MAX_MANIFEST_BYTES {
            return Err(HandlerError::bad_input(format!(
                "{}: {bytes} bytes, over the {MAX_MANIFEST_BYTES} bytes a manifest may have",
                self.key
            )));
        }
        self.main = Some((main.to_owned(), bytes));
        Ok(())
    }

    fn manifest_meshes(&mut self, _main: &str) -> Result<Vec<String>, HandlerError> {
        let text = self.store.get(self.key)?;
        let manifest = parse_manifest(&String::from_utf8_lossy(&text), Path::new(self.key))
            .map_err(|e| HandlerError::bad_input(e.to_string()))?;
        Ok(manifest.meshes)
    }

    fn check_name(
        &mut self,
        name: &str,
        kind: SceneFileKind,
        named_by: &str,
    ) -> Result<(), HandlerError> {
        check_relative(name, kind.noun())
            .map_err(|m| HandlerError::bad_input(format!("{}: {m}", self.source(named_by))))
    }

    fn take_mesh(&mut self, mesh: &str) -> Result<(), HandlerError> {
        self.copy_main()?;
        let Some(bytes) = self.size(mesh)? else {
            return Err(HandlerError::bad_input(format!(
                "{}: the mesh {} does not exist",
                self.key,
                self.source(mesh)
            )));
        };
        self.copy(mesh, bytes)
    }

    fn mesh_libraries(&mut self, mesh: &str) -> Result<Vec<String>, HandlerError> {
        self.copy_main()?;
        let bytes = self.sizes[mesh];
        material_libraries(self.store, &self.source(mesh), bytes)
    }

    fn take_library(&mut self, library: &str) -> Result<Option<Vec<String>>, HandlerError> {
        // A missing library is the loader's warning, as for uploaded scenes.
        let Some(bytes) = self.size(library)? else {
            return Ok(None);
        };
        self.copy(library, bytes)?;
        let text = self
            .store
            .get_range(&self.source(library), 0..MAX_LIBRARY_BYTES)?;
        Ok(Some(diffuse_map_files(&String::from_utf8_lossy(&text))))
    }

    fn take_texture(&mut self, texture: &str) -> Result<(), HandlerError> {
        // A missing texture is the loader's error, naming it.
        match self.size(texture)? {
            Some(bytes) => self.copy(texture, bytes),
            None => Ok(()),
        }
    }
}

/// The names after `mtllib` in the OBJ object `key` of `len` bytes, read in chunks of
/// [`SCAN_CHUNK_BYTES`] (a line cut by a chunk's end is read whole with the next).
fn material_libraries(
    store: &dyn BlobStore,
    key: &str,
    len: u64,
) -> Result<Vec<String>, HandlerError> {
    let mut libraries = Vec::new();
    let mut carry: Vec<u8> = Vec::new();
    let mut offset = 0;
    while offset < len {
        let chunk = store.get_range(key, offset..offset + SCAN_CHUNK_BYTES)?;
        offset += chunk.len() as u64;
        carry.extend_from_slice(&chunk);
        let whole = if offset >= len || chunk.is_empty() {
            carry.len()
        } else {
            carry
                .iter()
                .rposition(|&b| b == b'\n')
                .map_or(0, |at| at + 1)
        };
        libraries.extend(crate::api::material_libraries(&carry[..whole]));
        carry.drain(..whole);
        if chunk.is_empty() {
            break;
        }
    }
    Ok(libraries)
}

#[cfg(test)]
mod tests {
    use super::*;
    use hort_core::store::MemoryStore;

    fn request(key: &str) -> JobRequest {
        let mut request = super::super::tests::request("cornell.json");
        request.scene_key = Some(key.to_owned());
        request
    }

    #[test]
    fn a_manifest_its_meshes_and_their_libraries_are_copied_into_the_job() {
        let store = MemoryStore::new();
        store
            .put(
                "scenes/a/scene.json",
                br#"{"meshes": ["m/one.obj", "m/one.obj"]}"#,
            )
            .unwrap();
        // The mtllib line crosses no chunk here, but two libraries on one line both count.
        store
            .put(
                "scenes/a/m/one.obj",
                b"mtllib one.mtl gone.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            )
            .unwrap();
        // Diffuse textures beside their library are copied (options before the file name);
        // a missing one is left to the loader, which names it.
        store
            .put(
                "scenes/a/m/one.mtl",
                b"newmtl x\nmap_Kd -s 2 2 1 tex/wood.png\nnewmtl y\nmap_Kd gone.png\n",
            )
            .unwrap();
        store.put("scenes/a/m/tex/wood.png", b"png bytes").unwrap();
        store.put("scenes/a/other.obj", b"not this one").unwrap();
        let job = JobId::new("j1").unwrap();
        stage_in(&store, &job, &request("scenes/a/scene.json")).unwrap();
        assert_eq!(
            store.list("jobs/j1/scene/").unwrap(),
            [
                "jobs/j1/scene/m/one.mtl",
                "jobs/j1/scene/m/one.obj",
                "jobs/j1/scene/m/tex/wood.png",
                "jobs/j1/scene/scene.json"
            ]
        );
        assert_eq!(
            store.get("jobs/j1/scene/m/one.obj").unwrap(),
            store.get("scenes/a/m/one.obj").unwrap()
        );
    }

    /// A key naming an OBJ file is its own mesh: its material libraries and their textures
    /// come with it (they were left behind before the walk was shared).
    #[test]
    fn an_obj_keys_libraries_and_textures_are_copied_into_the_job() {
        let store = MemoryStore::new();
        store
            .put(
                "s/a.obj",
                b"mtllib a.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
            )
            .unwrap();
        store.put("s/a.mtl", b"newmtl x\nmap_Kd a.png\n").unwrap();
        store.put("s/a.png", b"png bytes").unwrap();
        let job = JobId::new("j1").unwrap();
        stage_in(&store, &job, &request("s/a.obj")).unwrap();
        assert_eq!(
            store.list("jobs/j1/scene/").unwrap(),
            [
                "jobs/j1/scene/a.mtl",
                "jobs/j1/scene/a.obj",
                "jobs/j1/scene/a.png"
            ]
        );
    }

    /// A manifest refused (too large, unparsable, or naming a mesh outside the folder) leaves
    /// nothing copied.
    #[test]
    fn a_refused_manifest_copies_nothing() {
        let store = MemoryStore::new();
        store
            .put("s/scene.json", br#"{"meshes": ["../up.obj"]}"#)
            .unwrap();
        let job = JobId::new("j1").unwrap();
        let e = stage_in(&store, &job, &request("s/scene.json")).unwrap_err();
        assert!(
            e.cause
                .starts_with("s/scene.json: mesh \"../up.obj\" is not a relative path"),
            "{}",
            e.cause
        );
        assert!(store.list("jobs/j1/").unwrap().is_empty());
    }

    #[test]
    fn a_missing_main_file_or_mesh_is_bad_input_naming_it() {
        let store = MemoryStore::new();
        let job = JobId::new("j1").unwrap();
        let e = stage_in(&store, &job, &request("scenes/none.json")).unwrap_err();
        assert_eq!(
            e.cause,
            "scene.key: there is no object scenes/none.json in the bucket"
        );
        store
            .put("scenes/a/scene.json", br#"{"meshes": ["gone.obj"]}"#)
            .unwrap();
        let e = stage_in(&store, &job, &request("scenes/a/scene.json")).unwrap_err();
        assert_eq!(
            e.cause,
            "scenes/a/scene.json: the mesh scenes/a/gone.obj does not exist"
        );
        assert_eq!(e.error_type, hort_core::ErrorType::BadInput);
    }

    #[test]
    fn libraries_are_found_across_chunk_ends() {
        let store = MemoryStore::new();
        let mut obj = vec![b'#'; SCAN_CHUNK_BYTES as usize - 4];
        obj.extend_from_slice(b"\nmtllib far.mtl\n");
        store.put("big.obj", &obj).unwrap();
        let found = material_libraries(&store, "big.obj", obj.len() as u64).unwrap();
        assert_eq!(found, ["far.mtl"]);
    }
}
