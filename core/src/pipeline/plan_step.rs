//! The plan step, shared by the in-process driver and the Plan function: store the scene's
//! textures, cut the scene into split objects (stored one at a time), plan the tasks, store the
//! plan.

use super::PipelineError;
use super::plan::{JobPlan, PlanRequest, plan_job, resolve_counts_with};
use super::split::split_scene_objects;
use super::split_object::SplitObject;
use super::textures::texture_objects;
use crate::ids::{JobId, SplitId};
use crate::keys::{plan_key, split_key};
use crate::scene::Scene;
use crate::store::{BlobStore, TimedStore};
use std::time::Instant;

/// A job planned into its store.
#[derive(Clone, Debug)]
pub struct PlannedJob {
    /// The plan, as stored at `jobs/{job}/plan.json`.
    pub plan: JobPlan,
    /// Bytes stored by the step: every split object plus the plan (textures not included:
    /// they are the scene's, like the scene object).
    pub bytes_written: u64,
    /// Where the step's time went: `task_us` in all, `encode_us` encoding split objects,
    /// `storage_us` storing them and the plan, `compute_us` the rest (assigning triangles to
    /// splits, building their BVHs, planning the tasks). Byte counts are left at 0: the caller's
    /// storage accounting has them.
    pub metrics: super::TaskMetrics,
}

/// Stores the scene's textures at `jobs/{job}/textures/`, splits `scene` as `request` asks
/// (counts checked by [`super::resolve_counts_with`], textures counted), stores each split
/// object at `jobs/{job}/splits/` as soon as it is built (the whole-scene acceleration data is
/// never held), then stores the plan. Deterministic: the same inputs store the same bytes.
pub fn plan_into_store(
    store: &dyn BlobStore,
    job: &JobId,
    scene: &Scene,
    request: &PlanRequest,
) -> Result<PlannedJob, PipelineError> {
    plan_into_store_keeping(store, job, scene, request, |_, _| {})
}

/// [`plan_into_store`] that also hands `keep` each split object as it is stored (id, object:
/// what decoding the stored bytes and attaching its textures gives back), for an in-process
/// caller that can keep it instead of decoding it again.
pub fn plan_into_store_keeping(
    store: &dyn BlobStore,
    job: &JobId,
    scene: &Scene,
    request: &PlanRequest,
    mut keep: impl FnMut(u32, SplitObject),
) -> Result<PlannedJob, PipelineError> {
    let started = Instant::now();
    let store = TimedStore::new(store);
    let mut encode_us = 0;
    let textures = &scene.mesh.textures;
    let (shape, s) = resolve_counts_with(request, scene.mesh.triangle_count() as u64, textures)?;
    let preset = super::split_build_preset(request, scene.mesh.triangle_count() as u64);
    let infos = split_scene_objects(
        &scene.mesh,
        shape.splits as usize,
        request.mode,
        preset,
        |split, mut object, bytes, encoded_in| {
            encode_us += encoded_in;
            store.put(&split_key(job, SplitId(split)), &bytes)?;
            object.attach(|id| {
                Ok::<_, crate::store::StoreError>(scene.mesh.textures[id as usize].clone())
            })?;
            keep(split, object);
            Ok::<(), crate::store::StoreError>(())
        },
    )?;
    let plan = plan_job(scene, request, infos, &shape, s)?;
    // Before the plan, which is what makes a job's tasks run.
    for (key, bytes) in texture_objects(job, textures, &plan.textures) {
        store.put(&key, &bytes)?;
    }
    let plan_json = serde_json::to_vec_pretty(&plan)
        .map_err(|e| PipelineError::BadInput(format!("cannot encode the plan: {e}")))?;
    store.put(&plan_key(job), &plan_json)?;
    let task_us = super::micros(started.elapsed());
    let storage_us = store.waited_us();
    let metrics = super::TaskMetrics {
        task_us,
        compute_us: task_us.saturating_sub(encode_us + storage_us),
        encode_us,
        storage_us,
        ..Default::default()
    };
    Ok(PlannedJob {
        bytes_written: plan.scene_bytes() + plan_json.len() as u64,
        plan,
        metrics,
    })
}
