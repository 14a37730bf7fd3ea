//! The one fake [`RenderBackend`] of the tests (this crate's router tests, the `hort serve`
//! server's, the bad-input table's and the fuzzer's http target; feature `test-support` outside this crate): jobs in
//! memory, objects in a map.

use std::collections::BTreeMap;
use std::sync::Mutex;
use std::time::Duration;

use super::{
    ApiError, ImageAnswer, ImageFormat, JobSpec, JobState, JobStatus, PredictionModel,
    RenderBackend, StageProgress, Submission,
};

/// Keeps submitted jobs in memory (`job-0`, `job-1`, ..., each succeeded at once); objects
/// for scenes by key. With `capacity`, refuses (429) a job past that many.
#[derive(Default)]
pub struct Fake {
    /// The bucket's objects, by key.
    pub objects: BTreeMap<String, Vec<u8>>,
    /// The jobs submitted, in order: job `job-{i}` is `jobs[i]`.
    pub jobs: Mutex<Vec<JobSpec>>,
    /// The most jobs it takes; `None`: no limit.
    pub capacity: Option<usize>,
    /// Every object read whole, and every range read, in order.
    pub reads: Mutex<Vec<String>>,
    /// Sizes to report for objects not held (a HEAD of a huge object).
    pub sizes: BTreeMap<String, u64>,
    /// How long a listing takes (a slow backend).
    pub list_delay: Duration,
}

impl RenderBackend for Fake {
    fn read_object(&self, key: &str) -> Result<Option<Vec<u8>>, ApiError> {
        self.reads.lock().unwrap().push(key.to_owned());
        Ok(self.objects.get(key).cloned())
    }
    fn object_size(&self, key: &str) -> Result<Option<u64>, ApiError> {
        let held = self.objects.get(key).map(|b| b.len() as u64);
        Ok(held.or_else(|| self.sizes.get(key).copied()))
    }
    fn read_object_range(
        &self,
        key: &str,
        range: std::ops::Range<u64>,
    ) -> Result<Vec<u8>, ApiError> {
        self.reads
            .lock()
            .unwrap()
            .push(format!("{key} {}..{}", range.start, range.end));
        let bytes = self.objects.get(key).map_or(&[][..], Vec::as_slice);
        let end = (range.end as usize).min(bytes.len());
        Ok(bytes[(range.start as usize).min(end)..end].to_vec())
    }
    fn prediction_model(&self) -> PredictionModel {
        PredictionModel::reference(4)
    }
    fn submit(&self, job: JobSpec) -> Result<Submission, ApiError> {
        let mut jobs = self.jobs.lock().unwrap();
        if let Some(key) = &job.idempotency_key
            && let Some(i) = jobs
                .iter()
                .position(|j| j.idempotency_key.as_ref() == Some(key))
        {
            return Ok(Submission {
                job: format!("job-{i}"),
                replayed: true,
            });
        }
        if let Some(cap) = self.capacity
            && jobs.len() >= cap
        {
            return Err(ApiError::too_many_jobs(format!(
                "{cap} jobs are running, the most this server runs at once"
            )));
        }
        jobs.push(job);
        Ok(Submission {
            job: format!("job-{}", jobs.len() - 1),
            replayed: false,
        })
    }
    fn status(&self, job: &str) -> Result<JobStatus, ApiError> {
        let jobs = self.jobs.lock().unwrap();
        let i: usize = job
            .strip_prefix("job-")
            .and_then(|n| n.parse().ok())
            .filter(|&i| i < jobs.len())
            .ok_or_else(|| ApiError::not_found(format!("no render {job:?}")))?;
        Ok(JobStatus {
            job: job.to_owned(),
            status: JobState::Succeeded,
            stage: Some("combine".into()),
            tasks_done: jobs[i].prediction.tasks_total,
            tasks_total: jobs[i].prediction.tasks_total,
            retried_attempts: 0,
            elapsed_seconds: 1.0,
            cost_usd: Some(0.001),
            predicted_cost_usd: jobs[i].prediction.predicted_cost_usd,
            max_cost_usd: jobs[i].max_cost_usd,
            error: None,
            image_url: None,
            scene: Some(jobs[i].scene_name.clone()),
            stages: jobs[i]
                .prediction
                .stages
                .iter()
                .map(|s| StageProgress {
                    stage: s.stage.clone(),
                    done: s.tasks,
                    total: s.tasks,
                })
                .collect(),
            outputs: jobs[i].request.outputs,
            frames: Vec::new(),
            frames_done: None,
        })
    }
    fn list(&self, limit: usize) -> Result<Vec<JobStatus>, ApiError> {
        std::thread::sleep(self.list_delay);
        let n = self.jobs.lock().unwrap().len();
        (0..n)
            .rev()
            .take(limit)
            .map(|i| self.status(&format!("job-{i}")))
            .collect()
    }
    fn image(
        &self,
        job: &str,
        format: ImageFormat,
        frame: Option<u32>,
    ) -> Result<ImageAnswer, ApiError> {
        self.status(job)?;
        let name = match frame {
            Some(k) => format!("frame {k} {}", format.extension()),
            None => format.extension().to_owned(),
        };
        Ok(ImageAnswer::Bytes(name.into_bytes()))
    }
    fn report(&self, job: &str) -> Result<Vec<u8>, ApiError> {
        self.status(job)?;
        Ok(b"{}".to_vec())
    }
    fn cancel(&self, job: &str) -> Result<JobStatus, ApiError> {
        self.status(job)
    }
}
