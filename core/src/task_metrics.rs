//! What one task did ([`TaskMetrics`]), and the timers that measure it: a leaf that the
//! pipeline's tasks fill in and the report's breakdown (`crate::breakdown`) reads.

use crate::adaptive::AdaptiveCounts;
use std::time::Instant;

/// What one task did, for the stage metrics of the report.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct TaskMetrics {
    /// Bytes fetched from storage (compressed), split objects included.
    pub bytes_read: u64,
    /// Of `bytes_read`, bytes of split objects.
    pub split_bytes_read: u64,
    /// Bytes stored (compressed).
    pub bytes_written: u64,
    /// Bytes of the records before compression.
    pub bytes_written_raw: u64,
    /// Records written.
    pub records: u64,
    /// Input blocks recomputed from their lineage.
    pub recomputed: u64,
    /// Logical shadow rays (hit samples x lights), counted by TraceReduce.
    pub shadow_rays: u64,
    /// Map tasks that found no work and did not load their split.
    pub skipped_tasks: u64,
    /// Split objects taken from the worker's split cache instead of storage.
    #[serde(default)]
    pub split_cache_hits: u64,
    /// Microseconds of the task's own run, from the start of its work to its end (for the
    /// Worker function: from reading `plan.json` to the last output written). The four parts
    /// below are measured inside it and never overlap, so their sum is at most this; the rest
    /// is bookkeeping (allocation, cache locks, key formatting).
    #[serde(default)]
    pub task_us: u64,
    /// Microseconds in the stage functions (ray casting, reduction, routing, shading, image
    /// assembly) and in rebuilding lost split objects from the scene.
    #[serde(default)]
    pub compute_us: u64,
    /// Microseconds encoding outputs: records into shuffle blocks with their compression, and
    /// the final PNG, PFM and hit buffer.
    #[serde(default)]
    pub encode_us: u64,
    /// Microseconds decoding inputs: shuffle blocks (decompression and records), split
    /// objects and the plan's JSON.
    #[serde(default)]
    pub decode_us: u64,
    /// Microseconds inside storage calls (`BlobStore::get` and `BlobStore::put`): the
    /// wait for the object store, its client's retries included.
    #[serde(default)]
    pub storage_us: u64,
    /// The most memory the task held at once, bytes, as its function measured it (the
    /// emulator's in-process invoker or the Worker binary, with the `hort-task-memory`
    /// allocator; docs/ARCHITECTURE.md, "Task memory"); 0 where nothing measured it, as in
    /// the pipeline's `run_task` itself. A measurement: it differs between runs of the same task. `+=` keeps
    /// the larger of the two, so a sum of tasks' metrics carries their maximum.
    #[serde(default)]
    pub peak_memory_bytes: u64,
    /// The adaptive sampler's decisions and samples (Render tasks of adaptive jobs).
    #[serde(default)]
    pub adaptive: AdaptiveCounts,
}

/// Whole microseconds of `d`, saturating.
pub fn micros(d: std::time::Duration) -> u64 {
    u64::try_from(d.as_micros()).unwrap_or(u64::MAX)
}

/// Runs `f` and adds its wall time, in microseconds, to `slot`.
pub fn timed<T>(slot: &mut u64, f: impl FnOnce() -> T) -> T {
    let started = Instant::now();
    let out = f();
    *slot += micros(started.elapsed());
    out
}

impl std::ops::AddAssign for TaskMetrics {
    fn add_assign(&mut self, o: TaskMetrics) {
        self.bytes_read += o.bytes_read;
        self.split_bytes_read += o.split_bytes_read;
        self.bytes_written += o.bytes_written;
        self.bytes_written_raw += o.bytes_written_raw;
        self.records += o.records;
        self.recomputed += o.recomputed;
        self.shadow_rays += o.shadow_rays;
        self.skipped_tasks += o.skipped_tasks;
        self.split_cache_hits += o.split_cache_hits;
        self.task_us += o.task_us;
        self.compute_us += o.compute_us;
        self.encode_us += o.encode_us;
        self.decode_us += o.decode_us;
        self.storage_us += o.storage_us;
        self.peak_memory_bytes = self.peak_memory_bytes.max(o.peak_memory_bytes);
        self.adaptive += o.adaptive;
    }
}
