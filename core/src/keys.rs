//! The object key layout: the one place that spells every key a job reads or writes.
//!
//! ```text
//! jobs/{job}/manifest.json                       the job request, created once
//! jobs/{job}/scene/{path}                       the scene files, relative to the main file
//! jobs/{job}/scene/scene.bin                     or the parsed scene, binary (scene_format binary)
//! jobs/{job}/plan.json                           the job plan (splits, spans, tasks)
//! jobs/{job}/splits/{split:05}.bin               one scene split with its BVH
//! jobs/{job}/{stage}/{task:05}/part-{p:05}       one shuffle partition of one task's output
//! jobs/{job}/items/{stage}.json                 the task items of one Map state
//! jobs/{job}/parts/table.json                    a scene split by tasks: its files and ranges
//! jobs/{job}/parts/vertices-{range:05}          the vertices one range of the scene defines
//! jobs/{job}/parts/records-{range:05}           one range's triangles, by spatial key
//! jobs/{job}/parts/index-{range:05}.json        what the records object holds, and where
//! jobs/{job}/parts/splits.json                   which records each split takes, the frame
//! jobs/{job}/parts/split-{split:05}.json         the summary of a split a build task stored
//! jobs/{job}/out/image.{ext}                     the final image (png, pfm)
//! jobs/{job}/out/hits.bin                        the hit buffer
//! jobs/{job}/frames/{frame:05}/...               one frame's partitions and out/ (a job of
//!                                                several frames; see [`FrameKeys`])
//! jobs/{job}/api.json                            the HTTP API's record of the job, created once
//! jobs/{job}/execution.json                      hort serve's record of the job's run
//! jobs/{job}/report.json                         the report of a job hort serve ran
//! ```
//!
//! Indices are zero-padded to five digits so that, below 100 000, listing a prefix returns tasks
//! and partitions in numeric order (lists are sorted by bytes). Larger indices still produce
//! unique keys, with more digits. Keys this module makes contain only `[a-z0-9-./]` plus the image
//! extension, all safe in S3 without escaping; scene files keep the names the user gave them
//! under `jobs/{job}/scene/`. Keys do not contain the attempt: every attempt of a task writes the
//! same bytes to the same keys.

use crate::ids::{JobId, PartitionId, SplitId, TaskId};
use crate::stage::Stage;
use std::fmt;

/// Where one frame's own objects live (its shuffle partitions and its `out/`), as the `{job}`
/// of [`partition_key`], [`image_key`] and [`hits_key`]: the job's own folder for a job of one
/// frame (`frame` `None`), else `jobs/{job}/frames/{frame:05}/`. What the frames share (the
/// request, scene, plan, splits, textures and items) keeps the job's keys.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameKeys<'a> {
    /// The job.
    pub job: &'a JobId,
    /// The frame, in a job of several frames.
    pub frame: Option<u32>,
}

impl fmt::Display for FrameKeys<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.frame {
            None => write!(f, "{}", self.job),
            Some(frame) => write!(f, "{}/frames/{frame:05}", self.job),
        }
    }
}

/// `jobs/{job}/parts/table.json`: the scene's files and byte ranges, as the Plan function's
/// scan found them (a scene split by partition and build tasks).
pub fn parts_table_key(job: &JobId) -> String {
    format!("jobs/{job}/parts/table.json")
}

/// `jobs/{job}/parts/vertices-{range:05}`: the vertex positions and normals range `range`
/// of the scene defines.
pub fn parts_vertices_key(job: &JobId, range: u32) -> String {
    format!("jobs/{job}/parts/vertices-{range:05}")
}

/// `jobs/{job}/parts/records-{range:05}`: range `range`'s triangles, ordered by spatial key,
/// in frames.
pub fn parts_records_key(job: &JobId, range: u32) -> String {
    format!("jobs/{job}/parts/records-{range:05}")
}

/// `jobs/{job}/parts/index-{range:05}.json`: the index of [`parts_records_key`].
pub fn parts_index_key(job: &JobId, range: u32) -> String {
    format!("jobs/{job}/parts/index-{range:05}.json")
}

/// `jobs/{job}/parts/splits.json`: which records each split takes, and the local frame.
pub fn parts_splits_key(job: &JobId) -> String {
    format!("jobs/{job}/parts/splits.json")
}

/// `jobs/{job}/parts/split-{split:05}.json`: the summary of a split a build task stored.
pub fn parts_split_info_key(job: &JobId, split: u32) -> String {
    format!("jobs/{job}/parts/split-{split:05}.json")
}

/// `jobs/{job}/manifest.json`: the job request, written once with a conditional put.
pub fn manifest_key(job: &JobId) -> String {
    format!("jobs/{job}/manifest.json")
}

/// `jobs/{job}/api.json`: the HTTP API's record of a job it accepted (what was asked, predicted
/// and when), created once with a conditional put, by the deployment's API function and by
/// `hort serve` alike.
pub fn api_record_key(job: &JobId) -> String {
    format!("jobs/{job}/api.json")
}

/// `jobs/{job}/execution.json`: `hort serve`'s record of a job's run (state, progress, times,
/// cost, error), which a deployment's Step Functions execution keeps instead.
pub fn execution_record_key(job: &JobId) -> String {
    format!("jobs/{job}/execution.json")
}

/// `jobs/{job}/report.json`: the report (`hort render --report`'s JSON) of a job `hort serve`
/// ran.
pub fn report_key(job: &JobId) -> String {
    format!("jobs/{job}/report.json")
}

/// Whether a job that succeeded keeps `key` when its intermediates are deleted: the job
/// request, the plan, the outputs (each frame's too), and the API's records and report.
pub fn kept_after_success(job: &JobId, key: &str) -> bool {
    let Some(rel) = key.strip_prefix(&format!("jobs/{job}/")) else {
        return true;
    };
    let frame_output = rel
        .strip_prefix("frames/")
        .and_then(|r| r.split_once('/'))
        .is_some_and(|(frame, r)| parse_index(frame).is_some() && r.starts_with("out/"));
    matches!(
        rel,
        "manifest.json" | "plan.json" | "api.json" | "execution.json" | "report.json"
    ) || rel.starts_with("out/")
        || frame_output
}

/// Whether a cancelled job keeps `key`: its request, its scene and the API's records stay (the
/// id stays taken, and the job can be inspected); everything it made goes.
pub fn kept_on_cancel(job: &JobId, key: &str) -> bool {
    let Some(rel) = key.strip_prefix(&format!("jobs/{job}/")) else {
        return true;
    };
    matches!(rel, "manifest.json" | "api.json" | "execution.json") || rel.starts_with("scene/")
}

/// `jobs/{job}/plan.json`: the job plan.
pub fn plan_key(job: &JobId) -> String {
    format!("jobs/{job}/plan.json")
}

/// `jobs/{job}/splits/{split:05}.bin`: one scene split.
pub fn split_key(job: &JobId, split: SplitId) -> String {
    format!("jobs/{job}/splits/{:05}.bin", split.0)
}

/// `jobs/{job}/textures/{content_key}.tex`: one of the job's textures, stored once by the plan
/// step under its content key.
pub fn texture_key(job: &JobId, content_key: &str) -> String {
    format!("jobs/{job}/textures/{content_key}.tex")
}

/// `jobs/{job}/{stage}/{task:05}/part-{p:05}`: partition `p` of the output of one task (`job`
/// a [`JobId`], or a [`FrameKeys`] for one frame's). [`parse_partition_key`] inverts it
/// exactly.
pub fn partition_key(
    job: &impl fmt::Display,
    stage: Stage,
    task: TaskId,
    partition: PartitionId,
) -> String {
    format!("jobs/{job}/{stage}/{:05}/part-{:05}", task.0, partition.0)
}

/// `jobs/{job}/out/image.{ext}`: the final image in another format; `ext` is given without the
/// dot (`"pfm"`, `"exr"`). A leading dot, if present, is dropped so `".pfm"` gives the same key.
pub fn image_key(job: &impl fmt::Display, ext: &str) -> String {
    let ext = ext.strip_prefix('.').unwrap_or(ext);
    format!("jobs/{job}/out/image.{ext}")
}

/// `jobs/{job}/scene/`: the scene files of the job (the main file and what it names), stored
/// by the client under their paths relative to the main file's folder.
pub fn scene_prefix(job: &JobId) -> String {
    format!("jobs/{job}/scene/")
}

/// `jobs/{job}/scene/scene.bin`: the parsed scene in the binary scene format
/// (`hort_core::scene::encode_scene`), stored instead of the scene files by a client that
/// parsed the scene already (a job request with `scene_format` `binary`). Under
/// [`scene_prefix`], so whatever deletes or lists the scene covers it; a job of the `files`
/// format never reads it, so a user's file of that name cannot be mistaken for it.
pub fn scene_binary_key(job: &JobId) -> String {
    format!("jobs/{job}/scene/scene.bin")
}

/// `jobs/{job}/out/hits.bin`: the hit buffer of the command-line contract (`job` a
/// [`JobId`], or a [`FrameKeys`] for one frame's).
pub fn hits_key(job: &impl fmt::Display) -> String {
    format!("jobs/{job}/out/hits.bin")
}

/// `jobs/{job}/items/{stage}.json`: the JSON array of task items a Map state reads.
pub fn items_key(job: &JobId, stage: Stage) -> String {
    format!("jobs/{job}/items/{stage}.json")
}

/// `jobs/{job}/items/{stage}-round-2.json`: the items of a stage's second round (a staged
/// adaptive job's refined spans; see [`crate::pipeline::JobPlan::round_of`]).
pub fn round_two_items_key(job: &JobId, stage: Stage) -> String {
    format!("jobs/{job}/items/{stage}-round-2.json")
}

/// `jobs/{job}/map-results`: where the Distributed Maps' `ResultWriter`s write each Map Run's
/// results (`{prefix}/{map run}/manifest.json` and the result files it names), so nothing of
/// them travels through the 256 KiB state payload.
pub fn map_results_prefix(job: &JobId) -> String {
    format!("jobs/{job}/map-results")
}

/// `{map run folder}/lost.json` beside a Map Run's `manifest.json`: the items its children lost
/// after their retries, which the stage's rerun Map reads. `None` unless `manifest_key` is a
/// manifest under `job`'s [`map_results_prefix`] (one folder deep), so one job's Lost step
/// cannot read or write another's keys.
pub fn lost_items_key(job: &JobId, manifest_key: &str) -> Option<String> {
    let prefix = map_results_prefix(job);
    let run = manifest_key
        .strip_prefix(prefix.as_str())?
        .strip_prefix('/')?
        .strip_suffix("/manifest.json")?;
    let safe = !run.is_empty() && !run.contains('/') && run != "." && run != "..";
    safe.then(|| format!("{prefix}/{run}/lost.json"))
}

/// A shuffle partition's key, parsed ([`parse_partition_key`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PartitionKey {
    /// The job.
    pub job: JobId,
    /// The frame, for a key under [`FrameKeys`] of a frame.
    pub frame: Option<u32>,
    /// The producing task's stage.
    pub stage: Stage,
    /// The producing task.
    pub task: TaskId,
    /// The partition.
    pub partition: PartitionId,
}

/// Parses a key made by [`partition_key`] (of a job, or of one of its frames); `None` for any
/// other string.
///
/// Guarantee: `parse_partition_key(k) == Some(x)` exactly when `partition_key(x) == k`, so a
/// listed key is accepted only in its canonical spelling (five or more digits, no extra zeros).
pub fn parse_partition_key(key: &str) -> Option<PartitionKey> {
    let parts: Vec<&str> = key.split('/').collect();
    let (job, frame, rest) = match parts.as_slice() {
        ["jobs", job, rest @ ..] if rest.len() == 3 => (job, None, rest),
        ["jobs", job, "frames", frame, rest @ ..] if rest.len() == 3 => {
            (job, Some(parse_index(frame)?), rest)
        }
        _ => return None,
    };
    let [stage, task, part] = rest else {
        return None;
    };
    Some(PartitionKey {
        job: JobId::new(*job).ok()?,
        frame,
        stage: stage.parse::<Stage>().ok()?,
        task: TaskId(parse_index(task)?),
        partition: PartitionId(parse_index(part.strip_prefix("part-")?)?),
    })
}

/// A decimal index in the canonical `{:05}` spelling, else `None`.
fn parse_index(text: &str) -> Option<u32> {
    if !text.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    let index: u32 = text.parse().ok()?;
    (format!("{index:05}") == text).then_some(index)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn job() -> JobId {
        JobId::new("job-42").unwrap()
    }

    #[test]
    fn lost_items_sit_beside_their_map_runs_manifest_of_the_same_job() {
        let j = job();
        assert_eq!(map_results_prefix(&j), "jobs/job-42/map-results");
        assert_eq!(
            lost_items_key(&j, "jobs/job-42/map-results/CastMap-3/manifest.json").as_deref(),
            Some("jobs/job-42/map-results/CastMap-3/lost.json")
        );
        for foreign in [
            "jobs/job-43/map-results/CastMap-3/manifest.json",
            "jobs/job-42/map-results/manifest.json",
            "jobs/job-42/map-results/a/b/manifest.json",
            "jobs/job-42/map-results/../manifest.json",
            "jobs/job-42/map-results/CastMap-3/SUCCEEDED_0.json",
            "jobs/job-42/map-resultsX/CastMap-3/manifest.json",
        ] {
            assert_eq!(lost_items_key(&j, foreign), None, "{foreign}");
        }
    }

    #[test]
    fn keys_are_the_documented_strings() {
        let j = job();
        assert_eq!(manifest_key(&j), "jobs/job-42/manifest.json");
        assert_eq!(plan_key(&j), "jobs/job-42/plan.json");
        assert_eq!(split_key(&j, SplitId(1)), "jobs/job-42/splits/00001.bin");
        assert_eq!(
            split_key(&j, SplitId(123_456)),
            "jobs/job-42/splits/123456.bin"
        );
        assert_eq!(
            partition_key(&j, Stage::CastMap, TaskId(3), PartitionId(12)),
            "jobs/job-42/cast-map/00003/part-00012"
        );
        assert_eq!(image_key(&j, "pfm"), "jobs/job-42/out/image.pfm");
        assert_eq!(image_key(&j, ".exr"), "jobs/job-42/out/image.exr");
        assert_eq!(hits_key(&j), "jobs/job-42/out/hits.bin");
        let frame = FrameKeys {
            job: &j,
            frame: Some(3),
        };
        assert_eq!(
            image_key(&frame, "png"),
            "jobs/job-42/frames/00003/out/image.png"
        );
        assert_eq!(hits_key(&frame), "jobs/job-42/frames/00003/out/hits.bin");
        assert_eq!(
            partition_key(&frame, Stage::CastMap, TaskId(3), PartitionId(12)),
            "jobs/job-42/frames/00003/cast-map/00003/part-00012"
        );
        let alone = FrameKeys {
            job: &j,
            frame: None,
        };
        assert_eq!(image_key(&alone, "png"), image_key(&j, "png"));
        assert_eq!(scene_prefix(&j), "jobs/job-42/scene/");
        assert_eq!(scene_binary_key(&j), "jobs/job-42/scene/scene.bin");
        assert_eq!(
            items_key(&j, Stage::TraceMap),
            "jobs/job-42/items/trace-map.json"
        );
        assert_eq!(api_record_key(&j), "jobs/job-42/api.json");
        assert_eq!(execution_record_key(&j), "jobs/job-42/execution.json");
        assert_eq!(report_key(&j), "jobs/job-42/report.json");
    }

    #[test]
    fn a_job_that_succeeded_keeps_its_request_plan_outputs_and_records_only() {
        let j = job();
        let frame = FrameKeys {
            job: &j,
            frame: Some(12),
        };
        for kept in [
            manifest_key(&j),
            plan_key(&j),
            image_key(&j, "png"),
            hits_key(&j),
            api_record_key(&j),
            execution_record_key(&j),
            report_key(&j),
            image_key(&frame, "png"),
            hits_key(&frame),
        ] {
            assert!(kept_after_success(&j, &kept), "{kept}");
        }
        for gone in [
            scene_binary_key(&j),
            split_key(&j, SplitId(0)),
            items_key(&j, Stage::Render),
            partition_key(&j, Stage::Render, TaskId(0), PartitionId(0)),
            partition_key(&frame, Stage::Render, TaskId(0), PartitionId(0)),
        ] {
            assert!(!kept_after_success(&j, &gone), "{gone}");
        }
    }

    #[test]
    fn a_cancelled_job_keeps_its_request_scene_and_records_only() {
        let j = job();
        for kept in [
            manifest_key(&j),
            api_record_key(&j),
            execution_record_key(&j),
            scene_binary_key(&j),
            format!("{}teapot.obj", scene_prefix(&j)),
            "jobs/job-421/plan.json".into(),
        ] {
            assert!(kept_on_cancel(&j, &kept), "{kept}");
        }
        for gone in [
            plan_key(&j),
            report_key(&j),
            split_key(&j, SplitId(0)),
            image_key(&j, "png"),
            items_key(&j, Stage::CastMap),
            partition_key(&j, Stage::CastMap, TaskId(0), PartitionId(0)),
        ] {
            assert!(!kept_on_cancel(&j, &gone), "{gone}");
        }
    }

    #[test]
    fn padded_indices_list_in_numeric_order() {
        let j = job();
        let mut keys: Vec<String> = [10, 9, 99_999, 0, 100]
            .into_iter()
            .map(|p| partition_key(&j, Stage::CastReduce, TaskId(1), PartitionId(p)))
            .collect();
        keys.sort();
        let order: Vec<u32> = keys
            .iter()
            .filter_map(|k| parse_partition_key(k))
            .map(|k| k.partition.0)
            .collect();
        assert_eq!(order, [0, 9, 10, 100, 99_999]);
    }

    #[test]
    fn parse_partition_key_round_trips() {
        let j = job();
        for stage in Stage::ALL {
            for (t, p) in [(0, 0), (1, 99_999), (100_000, 7), (u32::MAX, u32::MAX)] {
                for frame in [None, Some(0), Some(7), Some(123_456)] {
                    let scope = FrameKeys { job: &j, frame };
                    let key = partition_key(&scope, stage, TaskId(t), PartitionId(p));
                    let expected = PartitionKey {
                        job: j.clone(),
                        frame,
                        stage,
                        task: TaskId(t),
                        partition: PartitionId(p),
                    };
                    assert_eq!(parse_partition_key(&key), Some(expected), "{key}");
                }
            }
        }
    }

    #[test]
    fn parse_partition_key_rejects_everything_else() {
        for bad in [
            "",
            "jobs/job-42/cast-map/00003/part-00012/",
            "jobs/job-42/cast-map/00003/part-00012/x",
            "job/job-42/cast-map/00003/part-00012",
            "jobs/Job/cast-map/00003/part-00012",
            "jobs/job-42/castmap/00003/part-00012",
            "jobs/job-42/cast-map/0003/part-00012",
            "jobs/job-42/cast-map/000003/part-00012",
            "jobs/job-42/cast-map/00003/part-0012",
            "jobs/job-42/cast-map/00003/part-+0012",
            "jobs/job-42/cast-map/00003/prt-00012",
            "jobs/job-42/cast-map/-0003/part-00012",
            "jobs/job-42/cast-map/4294967296/part-00012",
            "jobs/job-42/splits/00001.bin",
            "jobs/job-42/manifest.json",
            "jobs/job-42/frames/0003/cast-map/00003/part-00012",
            "jobs/job-42/frame/00003/cast-map/00003/part-00012",
            "jobs/job-42/frames/00003/cast-map/00003/part-00012/x",
            "jobs/job-42/frames/00003/out/image.png",
        ] {
            assert_eq!(parse_partition_key(bad), None, "{bad}");
        }
    }
}
