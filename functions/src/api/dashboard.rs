//! `GET /`: the job dashboard, one self-contained HTML page (no build step, nothing from
//! elsewhere: its style, script and the bundled scenes are inline), rendered by the router
//! itself so `hort serve` and API Gateway serve the same page.
//!
//! Guarantees:
//! - Every string that comes from a request or a job (scene names, stages, error messages) is
//!   HTML-escaped by [`escape_html`] before it enters the page; the page's script only ever
//!   inserts the table this module renders, and writes answers of the API as text
//!   (`textContent`), never as HTML.
//! - Every URL in the page is relative (`renders`, `renders/{id}/image`), so the page works
//!   under an API Gateway stage (`https://.../prod/`) as on `http://127.0.0.1:8080/`.
//! - `GET /?view=jobs` answers the job table alone (the rows the page polls for while jobs
//!   run); `GET /` the whole page with the table as it is now.

use std::fmt::Write;

use super::backend::{JobState, JobStatus};
use hort_core::predict::usd;

/// Most jobs the dashboard lists (the newest).
pub const DASHBOARD_JOBS: usize = 50;

const TEMPLATE: &str = include_str!("dashboard.html");

/// A scene's files: (name relative to its folder, text).
type Files = &'static [(&'static str, &'static str)];

/// The scenes the page offers without an upload: (name, main file, files).
const BUNDLED: &[(&str, &str, Files)] = &[
    (
        "cornell",
        "cornell.json",
        &[
            (
                "cornell.json",
                include_str!("../../../scenes/cornell/cornell.json"),
            ),
            (
                "cornell.obj",
                include_str!("../../../scenes/cornell/cornell.obj"),
            ),
            (
                "cornell.mtl",
                include_str!("../../../scenes/cornell/cornell.mtl"),
            ),
        ],
    ),
    (
        "teapot",
        "teapot.json",
        &[
            (
                "teapot.json",
                include_str!("../../../scenes/teapot/teapot.json"),
            ),
            (
                "teapot.obj",
                include_str!("../../../scenes/teapot/teapot.obj"),
            ),
            (
                "ground.obj",
                include_str!("../../../scenes/teapot/ground.obj"),
            ),
            (
                "ground.mtl",
                include_str!("../../../scenes/teapot/ground.mtl"),
            ),
        ],
    ),
    (
        "bunny",
        "bunny.json",
        &[
            (
                "bunny.json",
                include_str!("../../../scenes/bunny/bunny.json"),
            ),
            ("bunny.obj", include_str!("../../../scenes/bunny/bunny.obj")),
            (
                "ground.obj",
                include_str!("../../../scenes/bunny/ground.obj"),
            ),
            (
                "ground.mtl",
                include_str!("../../../scenes/bunny/ground.mtl"),
            ),
        ],
    ),
];

/// Escapes `&`, `<`, `>`, `"` and `'`, so `text` is shown as text in element content and in
/// quoted attribute values.
pub fn escape_html(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// The bundled scenes as JSON (`{"cornell": {"main", "files"}}`) safe inside a `<script>`
/// element: every `<` is written `\u003c`, so no `</script>` can end it early.
fn bundled_json() -> String {
    let scenes: serde_json::Map<String, serde_json::Value> = BUNDLED
        .iter()
        .map(|(name, main, files)| {
            let files: serde_json::Map<String, serde_json::Value> = files
                .iter()
                .map(|(n, text)| ((*n).to_owned(), serde_json::Value::from(*text)))
                .collect();
            (
                (*name).to_owned(),
                serde_json::json!({"main": main, "files": files}),
            )
        })
        .collect();
    serde_json::Value::Object(scenes)
        .to_string()
        .replace('<', "\\u003c")
}

/// The whole page, with `jobs` (newest first) in its table.
pub fn page(jobs: &[JobStatus]) -> String {
    // The bundled scenes first: a job's text can then never be taken for a placeholder.
    TEMPLATE
        .replace("{{BUNDLED}}", &bundled_json())
        .replace("{{JOBS}}", &jobs_table(jobs))
}

/// The rows of the job table (`<tr>` elements), newest first; one row saying there are none
/// when `jobs` is empty. Each row has `data-job` and `data-status`; a running row has
/// `data-live`, which keeps the page polling.
pub fn jobs_table(jobs: &[JobStatus]) -> String {
    if jobs.is_empty() {
        return "<tr class=\"none\"><td colspan=\"9\">No jobs yet: submit one below.</td></tr>\n"
            .to_owned();
    }
    let mut out = String::new();
    for j in jobs {
        let _ = write_row(&mut out, j);
    }
    out
}

fn write_row(out: &mut String, j: &JobStatus) -> std::fmt::Result {
    let id = escape_html(&j.job);
    let state = j.status.as_str();
    let live = if j.status.is_final() {
        ""
    } else {
        " data-live=\"1\""
    };
    writeln!(out, "<tr data-job=\"{id}\" data-status=\"{state}\"{live}>")?;
    writeln!(out, "<td class=\"id\">{id}</td>")?;
    writeln!(
        out,
        "<td class=\"scene\">{}</td>",
        escape_html(j.scene.as_deref().unwrap_or("?"))
    )?;
    write!(
        out,
        "<td><span class=\"status {}\">{state}</span>",
        state.to_ascii_lowercase()
    )?;
    if let Some(e) = &j.error {
        write!(out, "<div class=\"error\">{}</div>", escape_html(e))?;
    }
    writeln!(out, "</td>")?;
    writeln!(
        out,
        "<td class=\"stage\">{}</td>",
        escape_html(j.stage.as_deref().unwrap_or("-"))
    )?;
    write_progress(out, j)?;
    writeln!(out, "<td class=\"num\">{}</td>", j.retried_attempts)?;
    writeln!(out, "<td class=\"num\">{:.1} s</td>", j.elapsed_seconds)?;
    let cost = match j.cost_usd {
        Some(c) => usd(c),
        None => format!("~{}", usd(j.predicted_cost_usd)),
    };
    let budget = match j.max_cost_usd {
        Some(b) => format!(" / {}", usd(b)),
        None => " / no budget".to_owned(),
    };
    writeln!(
        out,
        "<td class=\"num\">{}{}</td>",
        escape_html(&cost),
        budget
    )?;
    write!(out, "<td class=\"out\">")?;
    if j.status == JobState::Succeeded {
        write!(
            out,
            "<a href=\"renders/{id}/image\"><img class=\"result\" alt=\"image of {id}\" \
             src=\"renders/{id}/image\"></a><br>"
        )?;
        write_frame_strip(out, &id, &j.frames)?;
        // The linear formats only of a job that stored its linear image (others answer 404).
        if j.outputs.linear {
            write!(
                out,
                "<a href=\"renders/{id}/image?format=pfm\">PFM</a> \
                 <a href=\"renders/{id}/image?format=exr\">EXR</a> "
            )?;
        }
        write!(out, "<a href=\"renders/{id}/report\">report</a>")?;
    }
    if !j.status.is_final() {
        write!(
            out,
            "<button type=\"button\" class=\"cancel\" data-cancel=\"{id}\">Cancel</button>"
        )?;
    }
    writeln!(out, "</td>\n</tr>")
}

/// Most frames a job's row shows as thumbnails.
const STRIP_FRAMES: usize = 12;

/// A job of several frames: a strip of its first frames' thumbnails, each linking its image,
/// and a button that plays every frame in the job's image (the page's script).
fn write_frame_strip(out: &mut String, id: &str, frames: &[u32]) -> std::fmt::Result {
    if frames.is_empty() {
        return Ok(());
    }
    let list: Vec<String> = frames.iter().map(u32::to_string).collect();
    write!(out, "<div class=\"strip\">")?;
    for k in frames.iter().take(STRIP_FRAMES) {
        write!(
            out,
            "<a href=\"renders/{id}/frames/{k}/image\"><img alt=\"frame {k}\" \
             src=\"renders/{id}/frames/{k}/image\"></a>"
        )?;
    }
    write!(
        out,
        "</div><button type=\"button\" class=\"play\" data-play=\"{id}\" \
         data-frames=\"{}\">Play {} frames</button><br>",
        list.join(","),
        frames.len()
    )
}

/// One bar per stage (tasks done of the stage's tasks), or one bar over all tasks when the
/// backend does not count per stage.
fn write_progress(out: &mut String, j: &JobStatus) -> std::fmt::Result {
    write!(out, "<td class=\"progress\">")?;
    let overall = [(String::from("all"), j.tasks_done, j.tasks_total)];
    let per_stage: Vec<(String, u64, u64)> = j
        .stages
        .iter()
        .map(|s| (s.stage.clone(), s.done, s.total))
        .collect();
    let bars = if per_stage.is_empty() {
        &overall[..]
    } else {
        &per_stage[..]
    };
    for (stage, done, total) in bars {
        let stage = escape_html(stage);
        write!(
            out,
            "<div class=\"bar\" title=\"{stage}: {done} of {}\"><label>{stage}</label>\
             <progress max=\"{}\" value=\"{done}\"></progress><span>{done}/{total}</span></div>",
            hort_core::plural::count(*total, "task"),
            (*total).max(1)
        )?;
    }
    writeln!(out, "</td>")
}

#[cfg(test)]
mod tests {
    use super::*;
    use hort_core::pipeline::StoredOutputs;

    fn succeeded(outputs: StoredOutputs) -> JobStatus {
        JobStatus {
            job: "j1".into(),
            status: JobState::Succeeded,
            stage: Some("combine".into()),
            tasks_done: 2,
            tasks_total: 2,
            retried_attempts: 0,
            elapsed_seconds: 1.0,
            cost_usd: Some(0.001),
            predicted_cost_usd: 0.001,
            max_cost_usd: None,
            error: None,
            image_url: None,
            scene: Some("s.obj".into()),
            stages: Vec::new(),
            outputs,
            frames: Vec::new(),
            frames_done: None,
        }
    }

    /// A job of several frames shows its first frames as a strip of links and a button that
    /// plays them all; a job of one frame shows neither.
    #[test]
    fn a_job_of_frames_shows_a_strip_and_a_player() {
        let mut job = succeeded(StoredOutputs::PNG);
        assert!(!jobs_table(std::slice::from_ref(&job)).contains("strip"));
        job.frames = (0..20).collect();
        let table = jobs_table(&[job]);
        assert_eq!(
            table.matches("src=\"renders/j1/frames/").count(),
            STRIP_FRAMES
        );
        assert!(table.contains("<a href=\"renders/j1/frames/11/image\">"));
        assert!(!table.contains("renders/j1/frames/12/image"));
        let all: Vec<String> = (0..20).map(|k| k.to_string()).collect();
        assert!(table.contains(&format!(
            "data-play=\"j1\" data-frames=\"{}\">Play 20 frames</button>",
            all.join(",")
        )));
    }

    /// The links of a succeeded job: the linear formats only if it stored its linear image.
    #[test]
    fn a_job_links_only_the_formats_it_stored() {
        let links = |outputs| {
            let table = jobs_table(&[succeeded(outputs)]);
            let cell = table.split("<td class=\"out\">").nth(1).unwrap();
            cell[..cell.find("</td>").unwrap()].to_owned()
        };
        let image = "<a href=\"renders/j1/image\"><img class=\"result\" alt=\"image of j1\" \
                     src=\"renders/j1/image\"></a><br>";
        assert_eq!(
            links(StoredOutputs::PNG),
            format!("{image}<a href=\"renders/j1/report\">report</a>")
        );
        assert_eq!(
            links(StoredOutputs::ALL),
            format!(
                "{image}<a href=\"renders/j1/image?format=pfm\">PFM</a> <a \
                 href=\"renders/j1/image?format=exr\">EXR</a> <a \
                 href=\"renders/j1/report\">report</a>"
            )
        );
    }
}
