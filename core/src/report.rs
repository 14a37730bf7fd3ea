//! The `--report` JSON of the command-line contract (docs/ARCHITECTURE.md): one object with
//! `width`, `height`, `triangles`, `rays {primary, shadow}`, `seconds {total, render}`, `stages[]`,
//! `replication` and `cost_usd`. Fields that do not apply to a mode are null or empty
//! (`stages`, `replication` and `cost_usd` in monolithic mode; `cost_usd` in process).

pub use crate::adaptive::{AdaptiveCounts, AdaptiveSettings};
pub use crate::breakdown::StageBreakdown;
use serde::{Deserialize, Serialize};

/// A render report. Field names are part of the contract; more fields may be added.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Report {
    /// `"monolithic"`, `"pipeline"` (in process, `--in-process`) or `"emulator"`.
    pub mode: String,
    /// The scene file (OBJ or manifest) as named on the command line.
    pub scene: String,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Triangles in the scene.
    pub triangles: u64,
    /// Render threads (monolithic) or tasks run at once (pipeline modes).
    pub threads: usize,
    /// Logical rays traced.
    pub rays: RayReport,
    /// Where the wall-clock time went.
    pub seconds: Seconds,
    /// Each pipeline stage's measurements; empty in monolithic mode.
    pub stages: Vec<StageReport>,
    /// Scene replication: bytes of split objects the tasks read, over the bytes of all split
    /// objects. 1 means each split was read once; k-split jobs whose every span needs every
    /// split approach the number of spans. Null when no splits exist (monolithic).
    pub replication: Option<f64>,
    /// Estimated AWS cost of the render; null when it did not run as functions.
    pub cost_usd: Option<f64>,
    /// Task attempts that failed and were retried (timeouts, injected or real faults).
    #[serde(default)]
    pub retried_attempts: u64,
    /// Lost or corrupt blocks that tasks recomputed from their lineage.
    #[serde(default)]
    pub recomputed_blocks: u64,
    /// Scene splits k of the plan; null in monolithic mode.
    #[serde(default)]
    pub splits: Option<u32>,
    /// Pixel spans s of the plan; null in monolithic mode.
    #[serde(default)]
    pub spans: Option<u32>,
    /// `"fused"` or `"staged"`: how the plan ran the job; null in monolithic mode.
    #[serde(default)]
    pub execution: Option<String>,
    /// Why the plan chose that mode and split count; null in monolithic mode.
    #[serde(default)]
    pub execution_reason: Option<String>,
    /// How the BVH was built (`"quality"` or `"fast"`, [`crate::bvh::BuildPreset`]): the
    /// monolithic render's tree, or a job's split objects (the plan's choice). Null in reports
    /// that predate the field.
    #[serde(default)]
    pub bvh_build: Option<crate::bvh::BuildPreset>,
    /// Tasks running at once (function slots or worker threads); null in monolithic mode,
    /// where `threads` says it.
    #[serde(default)]
    pub workers: Option<usize>,
    /// The job's id (its objects are under `jobs/{job}/`); null when the run had no job.
    #[serde(default)]
    pub job: Option<String>,
    /// The files the run wrote.
    #[serde(default)]
    pub outputs: Outputs,
    /// The adaptive sampler's settings and what it did; null when it did not run.
    #[serde(default)]
    pub adaptive: Option<AdaptiveReport>,
    /// Work skipped because it cannot change the image, one sentence each (also printed on
    /// standard error as `skipped: ...`).
    #[serde(default)]
    pub skips: Vec<String>,
    /// A run of several frames: each frame and the image file written for it, in order
    /// (the totals above cover them all). Absent for a run of one image.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub frames: Vec<FrameReport>,
    /// A run of several frames: what its frames share, done once. Absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preparation: Option<Preparation>,
}

/// One frame of a run of several frames.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FrameReport {
    /// The frame's number.
    pub frame: u32,
    /// The image file written for it (the animated GIF's, for all frames of one).
    pub image: String,
    /// When the frame was ready, seconds after the run started: its render ended
    /// (monolithic), or the task that finished it assembled it (emulator); null where the run
    /// does not time frames (in-process).
    pub ready_seconds: Option<f64>,
    /// The frame's logical rays; null where the run does not count them per frame.
    pub rays: Option<RayReport>,
    /// The frame's own seconds: its render (monolithic), or its tasks' function time
    /// (emulator); null where not measured.
    pub seconds: Option<f64>,
    /// The frame's share of the run's cost, by its tasks' function time (emulator); null
    /// elsewhere.
    pub cost_usd: Option<f64>,
}

/// The one-time part of a run of several frames: loading the scene and building its BVH
/// (monolithic), or the plan step (emulator: the scene parsed, split and built), with its
/// share of the cost.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Preparation {
    /// Seconds.
    pub seconds: f64,
    /// Its share of the run's cost, by function time (emulator); null elsewhere.
    pub cost_usd: Option<f64>,
}

/// The adaptive sampler in a report: its settings and, where the run counts them, its
/// decisions (`spp` of the report is the base spp).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AdaptiveReport {
    /// Base spp, max spp and threshold.
    pub settings: AdaptiveSettings,
    /// Pixels refined, converged and background-only, and samples traced; null where the
    /// run does not count them.
    pub counts: Option<AdaptiveCounts>,
}

/// The files a render wrote; null where not asked for (`report` is `-` for standard output).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Outputs {
    /// The image.
    pub image: Option<String>,
    /// The hit buffer.
    pub hits: Option<String>,
    /// The report itself.
    pub report: Option<String>,
}

/// Logical ray counts: one primary ray per sample, one shadow ray per hit sample and light.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct RayReport {
    /// Camera rays: width × height × spp.
    pub primary: u64,
    /// Shadow rays: the number of lights for every sample that hit a triangle.
    pub shadow: u64,
}

/// Wall-clock seconds.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Seconds {
    /// From start to finish of the command, loading and writing included.
    pub total: f64,
    /// Ray work only: no loading, BVH build, storage or image writing.
    pub render: f64,
    /// Scene loading (parse) time.
    pub load: f64,
    /// Acceleration structure build time.
    pub build: f64,
}

/// One pipeline stage's measurements.
///
/// The `bytes_*` fields count one successful attempt per task: what the stage needs, the same
/// for every run of the same job whatever faults happen. What every attempt moved (failed
/// attempts, duplicate deliveries, stragglers abandoned past their timeout: the storage traffic
/// that is billed) is in `attempts_bytes_read` and `attempts_bytes_written`.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct StageReport {
    /// The stage's name (`plan`, `cast-map`, ..., `combine`).
    pub name: String,
    /// Tasks of the stage in the plan.
    pub tasks: u64,
    /// Attempts started: `tasks` plus retries (and duplicate deliveries).
    pub attempts: u64,
    /// Wall-clock seconds of the stage.
    pub seconds: f64,
    /// Bytes the tasks read (one successful attempt per task).
    pub bytes_read: u64,
    /// Compressed bytes the tasks wrote (one successful attempt per task).
    pub bytes_written: u64,
    /// The same records before compression: `bytes_written_raw / bytes_written` is the
    /// compression ratio.
    pub bytes_written_raw: u64,
    /// Bytes read from storage by every attempt.
    #[serde(default)]
    pub attempts_bytes_read: u64,
    /// Bytes written to storage by every attempt.
    #[serde(default)]
    pub attempts_bytes_written: u64,
    /// Where the stage's time went (seconds; see [`StageBreakdown`]). Measurements: reports
    /// of the same job differ here as in `seconds`. All zero in reports from before it.
    #[serde(default)]
    pub breakdown: StageBreakdown,
    /// The largest `peak_memory_bytes` of the stage's tasks (one successful attempt per task;
    /// for the plan stage, of its successful invocations): the most memory one of its tasks
    /// held at once. 0 where nothing is measured (`--in-process`, `--lambda-endpoint`'s Plan
    /// function, reports from before it). A measurement, like `seconds`.
    #[serde(default)]
    pub peak_memory_bytes: u64,
}

impl StageReport {
    /// Adds `later`, a later run of the same stage (round 2 of a staged adaptive job), into
    /// this row: counts, seconds, bytes and the time breakdown add up; the peak memory is the
    /// larger of the two.
    pub fn add(&mut self, later: &StageReport) {
        self.tasks += later.tasks;
        self.attempts += later.attempts;
        self.seconds += later.seconds;
        self.bytes_read += later.bytes_read;
        self.bytes_written += later.bytes_written;
        self.bytes_written_raw += later.bytes_written_raw;
        self.attempts_bytes_read += later.attempts_bytes_read;
        self.attempts_bytes_written += later.attempts_bytes_written;
        self.breakdown += later.breakdown;
        self.peak_memory_bytes = self.peak_memory_bytes.max(later.peak_memory_bytes);
    }
}

impl Report {
    /// Pretty JSON text of the report.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Report {
        Report {
            mode: "pipeline".into(),
            scene: "x.obj".into(),
            width: 64,
            height: 48,
            spp: 1,
            triangles: 12,
            threads: 2,
            rays: RayReport {
                primary: 3072,
                shadow: 100,
            },
            seconds: Seconds {
                total: 0.5,
                render: 0.25,
                load: 0.125,
                build: 0.0625,
            },
            stages: vec![StageReport {
                name: "trace".into(),
                tasks: 4,
                attempts: 5,
                seconds: 1.5,
                bytes_read: 1000,
                bytes_written: 300,
                bytes_written_raw: 900,
                attempts_bytes_read: 1100,
                attempts_bytes_written: 350,
                breakdown: StageBreakdown {
                    task: 2.5,
                    compute: 1.25,
                    encode: 0.5,
                    decode: 0.25,
                    storage: 0.375,
                    invocation: 0.125,
                    orchestration: 0.0625,
                },
                peak_memory_bytes: 123_456_789,
            }],
            replication: Some(1.25),
            cost_usd: None,
            retried_attempts: 2,
            recomputed_blocks: 1,
            splits: Some(3),
            spans: Some(4),
            execution: Some("staged".into()),
            execution_reason: Some("--splits 3: HORT's staged shuffle over 3 splits".into()),
            bvh_build: Some(crate::bvh::BuildPreset::Fast),
            workers: Some(2),
            job: Some("local".into()),
            outputs: Outputs {
                image: Some("x.png".into()),
                hits: None,
                report: Some("-".into()),
            },
            adaptive: Some(AdaptiveReport {
                settings: AdaptiveSettings {
                    base_spp: 4,
                    max_spp: 64,
                    threshold: 0.005,
                },
                counts: Some(AdaptiveCounts {
                    refined_pixels: 10,
                    background_pixels: 20,
                    converged_pixels: 3042,
                    samples: 12_888,
                }),
            }),
            skips: vec!["no lights: no shadow rays".into()],
            frames: Vec::new(),
            preparation: None,
        }
    }

    /// `sample()` as the contract's JSON, written by hand.
    const SAMPLE_JSON: &str = r#"{
  "mode": "pipeline",
  "scene": "x.obj",
  "width": 64,
  "height": 48,
  "spp": 1,
  "triangles": 12,
  "threads": 2,
  "rays": {
    "primary": 3072,
    "shadow": 100
  },
  "seconds": {
    "total": 0.5,
    "render": 0.25,
    "load": 0.125,
    "build": 0.0625
  },
  "stages": [
    {
      "name": "trace",
      "tasks": 4,
      "attempts": 5,
      "seconds": 1.5,
      "bytes_read": 1000,
      "bytes_written": 300,
      "bytes_written_raw": 900,
      "attempts_bytes_read": 1100,
      "attempts_bytes_written": 350,
      "breakdown": {
        "task": 2.5,
        "compute": 1.25,
        "encode": 0.5,
        "decode": 0.25,
        "storage": 0.375,
        "invocation": 0.125,
        "orchestration": 0.0625
      },
      "peak_memory_bytes": 123456789
    }
  ],
  "replication": 1.25,
  "cost_usd": null,
  "retried_attempts": 2,
  "recomputed_blocks": 1,
  "splits": 3,
  "spans": 4,
  "execution": "staged",
  "execution_reason": "--splits 3: HORT's staged shuffle over 3 splits",
  "bvh_build": "fast",
  "workers": 2,
  "job": "local",
  "outputs": {
    "image": "x.png",
    "hits": null,
    "report": "-"
  },
  "adaptive": {
    "settings": {
      "base_spp": 4,
      "max_spp": 64,
      "threshold": 0.005
    },
    "counts": {
      "refined_pixels": 10,
      "background_pixels": 20,
      "converged_pixels": 3042,
      "samples": 12888
    }
  },
  "skips": [
    "no lights: no shadow rays"
  ]
}"#;

    #[test]
    fn report_json_is_the_contract_text() {
        assert_eq!(sample().to_json(), SAMPLE_JSON);
    }

    #[test]
    fn report_parses_hand_written_json() {
        assert_eq!(
            serde_json::from_str::<Report>(SAMPLE_JSON).unwrap(),
            sample()
        );
        // A report from before the fault counters: they default to 0.
        let old = r#"{"mode": "monolithic", "scene": "x.obj", "width": 64, "height": 48,
            "spp": 1, "triangles": 12, "threads": 2, "rays": {"primary": 3072, "shadow": 100},
            "seconds": {"total": 0.5, "render": 0.25, "load": 0.125, "build": 0.0625},
            "stages": [], "replication": null, "cost_usd": 0.75}"#;
        let r: Report = serde_json::from_str(old).unwrap();
        assert_eq!((r.retried_attempts, r.recomputed_blocks), (0, 0));
        assert_eq!(
            (r.splits, r.spans, r.workers, r.job),
            (None, None, None, None)
        );
        assert_eq!(r.outputs, Outputs::default());
        assert_eq!((r.adaptive, r.skips.len()), (None, 0));
        assert_eq!(
            (r.mode.as_str(), r.cost_usd, r.replication),
            ("monolithic", Some(0.75), None)
        );
        assert!(r.stages.is_empty());
        // A stage from before the time breakdown: all of it 0.
        let stage = r#"{"name": "cast-map", "tasks": 2, "attempts": 2, "seconds": 0.5,
            "bytes_read": 1, "bytes_written": 2, "bytes_written_raw": 3}"#;
        let s: StageReport = serde_json::from_str(stage).unwrap();
        assert_eq!(s.breakdown, StageBreakdown::default());
        assert_eq!(s.peak_memory_bytes, 0, "before the memory measurement");
    }
}
