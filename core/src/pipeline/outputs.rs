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
}

/// Reads and decodes the image and hit buffer of `job`, the two at once; a missing object is a
/// storage error, a malformed one a [`PipelineError::Corrupt`] naming its key (the image's
/// error first when both fail).
pub fn read_outputs(
    store: &dyn BlobStore,
    job: &JobId,
    plan: &JobPlan,
) -> Result<JobOutputs, PipelineError> {
    let read_image = || {
        let pfm_key = image_key(job, "pfm");
        decode_pfm(&store.get(&pfm_key)?)
            .map_err(|e| PipelineError::Corrupt(format!("{pfm_key}: {e}")))
    };
    let read_hits = || {
        let hits_key = hits_key(job);
        decode_hits(&store.get(&hits_key)?, plan.width, plan.height)
            .map_err(|e| PipelineError::Corrupt(format!("{hits_key}: {e}")))
    };
    let (image, hits) = std::thread::scope(|scope| {
        let hits = scope.spawn(read_hits);
        let image = read_image();
        let hits = hits
            .join()
            .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
        (image, hits)
    });
    Ok(JobOutputs {
        image: image?,
        hits: hits?,
    })
}
