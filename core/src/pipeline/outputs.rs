//! Which outputs a job stores ([`StoredOutputs`]), and reading a finished job's outputs back
//! from its store: the one reader the in-process driver and the emulator share.

use super::PipelineError;
use super::plan::JobPlan;
use crate::hits::{Hit, decode_hits};
use crate::ids::JobId;
use crate::image::{Image, decode_pfm};
use crate::keys::{FrameKeys, hits_key, image_key};
use crate::store::BlobStore;
use serde::{Deserialize, Serialize};

/// Which outputs the Combine task stores besides the PNG (`jobs/{job}/out/image.png`, always
/// stored: it is the preview every client can show). The two others are large (at 1920x1080,
/// 24.9 MB of linear image and 16.6 MB of hits against about 1 MB of PNG), so a job stores
/// them only when asked. A request without this field asks for both, as before it existed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StoredOutputs {
    /// The linear image, `jobs/{job}/out/image.pfm` (the `.pfm` and `.exr` outputs are made
    /// from it).
    pub linear: bool,
    /// The hit buffer, `jobs/{job}/out/hits.bin`: per pixel a little-endian
    /// `{u32 triangle, f32 t}`.
    pub hits: bool,
}

impl StoredOutputs {
    /// Every output: the PNG, the linear image and the hit buffer.
    pub const ALL: StoredOutputs = StoredOutputs {
        linear: true,
        hits: true,
    };
    /// The PNG alone.
    pub const PNG: StoredOutputs = StoredOutputs {
        linear: false,
        hits: false,
    };

    /// True for [`StoredOutputs::ALL`], the default (left out of the JSON, so requests and plans
    /// that ask for everything keep their bytes).
    pub fn is_all(&self) -> bool {
        *self == StoredOutputs::ALL
    }
}

impl Default for StoredOutputs {
    fn default() -> Self {
        StoredOutputs::ALL
    }
}

/// What the Combine task stored, decoded.
#[derive(Clone, Debug)]
pub struct JobOutputs {
    /// The linear image (from `jobs/{job}/out/image.pfm`, bit-exact); `None` when the plan's
    /// [`StoredOutputs::linear`] is false.
    pub image: Option<Image>,
    /// The hit buffer, `plan.width x plan.height` records, row-major from the top-left; `None`
    /// when the plan's [`StoredOutputs::hits`] is false.
    pub hits: Option<Vec<Hit>>,
    /// The PNG as stored (`jobs/{job}/out/image.png`): `encode_png` of the linear image, byte
    /// for byte, so a caller writing a `.png` need not encode it again.
    pub png: Vec<u8>,
}

/// Reads the PNG of `job` (of its first frame, in a job of several frames) and the outputs
/// `plan.outputs` asks for with one
/// [`BlobStore::get_many`] (at once where the store can) and decodes the linear image and the
/// hit buffer; a missing object is a storage error, a malformed one a
/// [`PipelineError::Corrupt`] naming its key (in the order linear image, hits, PNG when
/// several fail).
pub fn read_outputs(
    store: &dyn BlobStore,
    job: &JobId,
    plan: &JobPlan,
) -> Result<JobOutputs, PipelineError> {
    let first = FrameKeys {
        job,
        frame: plan.frames.first().map(|f| f.frame),
    };
    read_outputs_of(store, &first, plan)
}

/// [`read_outputs`] of every frame of a job of several frames, in frame order: each frame's
/// number and outputs ([`crate::keys::FrameKeys`]); empty for a job of one frame.
pub fn read_frame_outputs(
    store: &dyn BlobStore,
    job: &JobId,
    plan: &JobPlan,
) -> Result<Vec<(u32, JobOutputs)>, PipelineError> {
    plan.frames
        .iter()
        .map(|f| {
            let scope = FrameKeys {
                job,
                frame: Some(f.frame),
            };
            Ok((f.frame, read_outputs_of(store, &scope, plan)?))
        })
        .collect()
}

/// [`read_outputs`] under `job`'s keys (a job's, or one frame's).
fn read_outputs_of(
    store: &dyn BlobStore,
    job: &impl std::fmt::Display,
    plan: &JobPlan,
) -> Result<JobOutputs, PipelineError> {
    let (pfm_key, hits_key, png_key) =
        (image_key(job, "pfm"), hits_key(job), image_key(job, "png"));
    let StoredOutputs {
        linear,
        hits: with_hits,
    } = plan.outputs;
    let mut keys = Vec::with_capacity(3);
    if linear {
        keys.push(pfm_key.clone());
    }
    if with_hits {
        keys.push(hits_key.clone());
    }
    keys.push(png_key);
    let mut fetched = store.get_many(&keys).into_iter();
    let mut next = || fetched.next().expect("get_many answers every key");
    let (pfm, hits, png) = (linear.then(&mut next), with_hits.then(&mut next), next());
    let image = pfm
        .map(|pfm| decode_pfm(&pfm?).map_err(|e| PipelineError::Corrupt(format!("{pfm_key}: {e}"))))
        .transpose()?;
    let hits = hits
        .map(|hits| {
            decode_hits(&hits?, plan.width, plan.height)
                .map_err(|e| PipelineError::Corrupt(format!("{hits_key}: {e}")))
        })
        .transpose()?;
    Ok(JobOutputs {
        image,
        hits,
        png: png?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pipeline::{PipelineOptions, PlanRequest, SplitMode, run_pipeline};
    use crate::store::MemoryStore;

    /// The Cornell box at 16x12 in `mode`, storing `outputs`: the run and the keys under
    /// `out/`.
    fn cornell(
        mode: super::super::ExecutionMode,
        outputs: StoredOutputs,
    ) -> (super::super::PipelineRun, Vec<String>) {
        let path = concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../scenes/cornell/cornell.json"
        );
        let scene = crate::scene::load_scene(std::path::Path::new(path)).unwrap();
        let store = MemoryStore::new();
        let options = PipelineOptions {
            job: JobId::new("outputs").unwrap(),
            workers: 2,
            split_cache_bytes: 1 << 24,
        };
        let request = PlanRequest {
            width: 16,
            height: 12,
            spp: 1,
            splits: None,
            spans: Some(3),
            mode: SplitMode::Spatial,
            execution: Some(mode),
            memory_mb: crate::pipeline::DEFAULT_MEMORY_MB,
            adaptive: None,
            outputs,
            frame: Default::default(),
        };
        let run = run_pipeline(&store, &scene, request, &options).unwrap();
        let mut keys = store.list("jobs/outputs/out/").unwrap();
        keys.sort();
        (run, keys)
    }

    #[test]
    fn a_job_stores_the_png_and_only_the_outputs_it_asks_for() {
        use super::super::ExecutionMode::{Fused, Staged};
        let png = "jobs/outputs/out/image.png".to_owned();
        let pfm = "jobs/outputs/out/image.pfm".to_owned();
        let hits = "jobs/outputs/out/hits.bin".to_owned();
        for mode in [Fused, Staged] {
            let (all, keys) = cornell(mode, StoredOutputs::ALL);
            assert_eq!(keys, [hits.clone(), pfm.clone(), png.clone()], "{mode:?}");
            let (all_image, all_hits) = (all.image.unwrap(), all.hits.unwrap());
            assert_eq!(all_hits.len(), 16 * 12);
            for (outputs, expected) in [
                (StoredOutputs::PNG, vec![png.clone()]),
                (
                    StoredOutputs {
                        linear: true,
                        hits: false,
                    },
                    vec![pfm.clone(), png.clone()],
                ),
                (
                    StoredOutputs {
                        linear: false,
                        hits: true,
                    },
                    vec![hits.clone(), png.clone()],
                ),
            ] {
                let (run, keys) = cornell(mode, outputs);
                assert_eq!(keys, expected, "{mode:?} {outputs:?}");
                assert_eq!(run.plan.outputs, outputs);
                // The same PNG whatever else is stored; what is read back is what was asked.
                assert_eq!(run.png, all.png, "{mode:?} {outputs:?}");
                assert_eq!(run.image.is_some(), outputs.linear);
                assert_eq!(run.hits.is_some(), outputs.hits);
                if let Some(image) = run.image {
                    assert_eq!(image.pixels, all_image.pixels);
                }
                if let Some(h) = run.hits {
                    assert_eq!(h, all_hits);
                }
            }
        }
    }

    #[test]
    fn outputs_default_to_all_and_only_other_choices_reach_the_json() {
        let all: PlanRequest = serde_json::from_str(
            r#"{"width":4,"height":3,"spp":1,"splits":null,"spans":null,"split_mode":"spatial"}"#,
        )
        .unwrap();
        assert_eq!(all.outputs, StoredOutputs::ALL);
        assert!(!serde_json::to_string(&all).unwrap().contains("outputs"));
        let png = PlanRequest {
            outputs: StoredOutputs::PNG,
            ..all
        };
        let json = serde_json::to_string(&png).unwrap();
        assert!(
            json.ends_with(r#""outputs":{"linear":false,"hits":false}}"#),
            "{json}"
        );
        assert_eq!(serde_json::from_str::<PlanRequest>(&json).unwrap(), png);
        let typo = json.replace("\"hits\"", "\"hit\"");
        assert_eq!(
            serde_json::from_str::<PlanRequest>(&typo)
                .unwrap_err()
                .to_string(),
            "unknown field `hit`, expected `linear` or `hits` at line 1 column 140"
        );
    }
}
