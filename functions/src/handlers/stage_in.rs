//! A scene given by key (`JobRequest::scene_key`), staged into its job: the Plan function copies
//! the main file, the meshes a manifest names and the material libraries the meshes name from
//! beside the key into `jobs/{job}/scene/`, inside the store (CopyObject). The function itself
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
use hort_core::scene::{diffuse_map_files, parse_manifest};
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
    let source = |name: &str| format!("{folder}{name}");
    let target = scene_prefix(job);
    let size = |name: &str| -> Result<Option<u64>, HandlerError> {
        match store.size(&source(name)) {
            Ok(size) => Ok(Some(size)),
            Err(StoreError::NotFound { .. }) => Ok(None),
            Err(e) => Err(e.into()),
        }
    };
    let copy = |name: &str, bytes: u64| -> Result<(), HandlerError> {
        if bytes > COPY_MAX_BYTES {
            return Err(HandlerError::bad_input(format!(
                "{}: {bytes} bytes, over the {COPY_MAX_BYTES} bytes S3 copies in one request; \
                 split the mesh into files of at most 5 GiB and list them in a manifest",
                source(name)
            )));
        }
        store.copy(&source(name), &format!("{target}{name}"))?;
        Ok(())
    };
    let Some(main_bytes) = size(&main)? else {
        return Err(HandlerError::bad_input(format!(
            "scene.key: there is no object {key} in the bucket"
        )));
    };
    let meshes = if is_manifest(&main) {
        if main_bytes > MAX_MANIFEST_BYTES {
            return Err(HandlerError::bad_input(format!(
                "{key}: {main_bytes} bytes, over the {MAX_MANIFEST_BYTES} bytes a manifest may have"
            )));
        }
        let text = store.get(key)?;
        let manifest = parse_manifest(&String::from_utf8_lossy(&text), Path::new(key))
            .map_err(|e| HandlerError::bad_input(e.to_string()))?;
        let mut meshes = Vec::new();
        for mesh in manifest.meshes {
            check_relative(&mesh, "mesh")
                .map_err(|m| HandlerError::bad_input(format!("{key}: {m}")))?;
            meshes.push(beside(&main, &mesh));
        }
        meshes
    } else {
        vec![main.clone()]
    };
    copy(&main, main_bytes)?;
    let mut copied = std::collections::BTreeSet::from([main.clone()]);
    for mesh in meshes {
        if !copied.insert(mesh.clone()) {
            continue;
        }
        let Some(bytes) = size(&mesh)? else {
            return Err(HandlerError::bad_input(format!(
                "{key}: the mesh {} does not exist",
                source(&mesh)
            )));
        };
        copy(&mesh, bytes)?;
        for library in material_libraries(store, &source(&mesh), bytes)? {
            check_relative(&library, "material library")
                .map_err(|m| HandlerError::bad_input(format!("{}: {m}", source(&mesh))))?;
            let library = beside(&mesh, &library);
            if copied.insert(library.clone())
                && let Some(bytes) = size(&library)?
            {
                // A missing library is the loader's warning, as for uploaded scenes.
                copy(&library, bytes)?;
                // Its diffuse textures; a missing one is the loader's error, naming it.
                let text = store.get_range(&source(&library), 0..MAX_LIBRARY_BYTES)?;
                for map in diffuse_map_files(&String::from_utf8_lossy(&text)) {
                    check_relative(&map, "texture").map_err(|m| {
                        HandlerError::bad_input(format!("{}: {m}", source(&library)))
                    })?;
                    let map = beside(&library, &map);
                    if copied.insert(map.clone())
                        && let Some(bytes) = size(&map)?
                    {
                        copy(&map, bytes)?;
                    }
                }
            }
        }
    }
    Ok(())
}

fn is_manifest(name: &str) -> bool {
    Path::new(name)
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("json"))
}

/// `rel` relative to the folder of `file` (both relative to the scene's folder).
fn beside(file: &str, rel: &str) -> String {
    match file.rsplit_once('/') {
        Some((dir, _)) => format!("{dir}/{rel}"),
        None => rel.to_owned(),
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
