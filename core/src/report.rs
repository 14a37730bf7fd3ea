//! The `--report` JSON of the command-line contract (docs/ARCHITECTURE.md): one object with
//! `width`, `height`, `triangles`, `rays {primary, shadow}`, `seconds {total, render}`, `stages[]`,
//! `replication` and `cost_usd`. Fields that do not apply to a mode are null or empty
//! (`stages`, `replication` and `cost_usd` in monolithic mode; `cost_usd` in process).

use serde::{Deserialize, Serialize};

/// A render report. Field names are part of the contract; more fields may be added.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Report {
    /// `"monolithic"`, `"pipeline"` (in process, `--in-process`) or `"emulator"`.
    pub mode: String,
    pub scene: String,
    pub width: u32,
    pub height: u32,
    pub spp: u32,
    pub triangles: u64,
    pub threads: usize,
    pub rays: RayReport,
    pub seconds: Seconds,
    pub stages: Vec<StageReport>,
    /// Split bytes read / scene bytes; null when no splits exist.
    pub replication: Option<f64>,
    /// Estimated AWS cost of the render; null when it did not run as functions.
    pub cost_usd: Option<f64>,
    /// Task attempts that failed and were retried (timeouts, injected or real faults).
    #[serde(default)]
    pub retried_attempts: u64,
    /// Lost or corrupt blocks that tasks recomputed from their lineage.
    #[serde(default)]
    pub recomputed_blocks: u64,
}

/// Logical ray counts: one primary ray per sample, one shadow ray per hit sample and light.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct RayReport {
    pub primary: u64,
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
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StageReport {
    pub name: String,
    pub tasks: u64,
    pub attempts: u64,
    pub seconds: f64,
    pub bytes_read: u64,
    /// Compressed bytes written.
    pub bytes_written: u64,
    /// Bytes written before compression.
    pub bytes_written_raw: u64,
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
            }],
            replication: Some(1.25),
            cost_usd: None,
            retried_attempts: 2,
            recomputed_blocks: 1,
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
      "bytes_written_raw": 900
    }
  ],
  "replication": 1.25,
  "cost_usd": null,
  "retried_attempts": 2,
  "recomputed_blocks": 1
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
            (r.mode.as_str(), r.cost_usd, r.replication),
            ("monolithic", Some(0.75), None)
        );
        assert!(r.stages.is_empty());
    }
}
