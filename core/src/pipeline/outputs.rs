//! Reading a finished job's outputs back from its store: the one reader the in-process driver
//! and the emulator share.

use super::PipelineError;
use super::plan::JobPlan;
use crate::hits::{Hit, decode_hits};
use crate::ids::JobId;
use crate::image::{Image, decode_pfm};
use crate::keys::{hits_key, image_key};
use crate::store::BlobStore;

/// What the Combine task stored, decoded.
#[derive(Clone, Debug)]
pub struct JobOutputs {
    /// The linear image (from `jobs/{job}/out/image.pfm`, bit-exact).
    pub image: Image,
    /// The hit buffer, `plan.width x plan.height` records, row-major from the top-left.
    pub hits: Vec<Hit>,
    /// The PNG as stored (`jobs/{job}/out/image.png`): `encode_png` of `image`, byte for byte,
    /// so a caller writing a `.png` need not encode it again.
    pub png: Vec<u8>,
}

/// Reads the image, hit buffer and PNG of `job` with one [`BlobStore::get_many`] (at once
/// where the store can) and decodes the first two; a missing object is a storage error, a
/// malformed one a [`PipelineError::Corrupt`] naming its key (in that order of objects when
/// several fail).
pub fn read_outputs(
    store: &dyn BlobStore,
    job: &JobId,
    plan: &JobPlan,
) -> Result<JobOutputs, PipelineError> {
    let (pfm_key, hits_key, png_key) =
        (image_key(job, "pfm"), hits_key(job), image_key(job, "png"));
    let [pfm, hits, png]: [_; 3] = store
        .get_many(&[pfm_key.clone(), hits_key.clone(), png_key])
        .try_into()
        .expect("get_many answers every key");
    let image = decode_pfm(&pfm?).map_err(|e| PipelineError::Corrupt(format!("{pfm_key}: {e}")))?;
    let hits = decode_hits(&hits?, plan.width, plan.height)
        .map_err(|e| PipelineError::Corrupt(format!("{hits_key}: {e}")))?;
    Ok(JobOutputs {
        image,
        hits,
        png: png?,
    })
}
