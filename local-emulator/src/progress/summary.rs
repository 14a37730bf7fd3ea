//! The summary tables printed after a pipelined render: traffic per stage
//! ([`print_summary`]) and where each stage's time went ([`print_breakdown`]).

use std::io::{self, Write};

use hort_core::report::{StageBreakdown, StageReport};

const HEADERS: [&str; 8] = [
    "stage",
    "tasks",
    "attempts",
    "time (s)",
    "MB read",
    "MB written",
    "compression",
    "peak MB",
];

/// Writes the per-stage table of a render, with a total row: tasks, attempts, seconds,
/// megabytes (10^6 bytes) read and written (compressed), and the compression ratio
/// (`bytes_written_raw / bytes_written`, `-` when nothing was written). The total's time is the
/// sum of the stages' times (they run one after another) and its ratio that of the sums. `peak
/// MB` is the most memory one task of the stage held ([`StageReport::peak_memory_bytes`]) in
/// MB of 2^20 bytes, as `--memory-mb` counts them (`-` where not measured); the total's is the
/// largest. Columns are aligned: the stage name to the left, numbers to the right.
pub fn print_summary(stages: &[StageReport], out: &mut dyn Write) -> io::Result<()> {
    let total = StageReport {
        name: "total".into(),
        tasks: stages.iter().map(|s| s.tasks).sum(),
        attempts: stages.iter().map(|s| s.attempts).sum(),
        // Not `sum()`: an empty f64 sum is -0.0, which prints as `-0.00`.
        seconds: stages.iter().fold(0.0, |t, s| t + s.seconds),
        bytes_read: stages.iter().map(|s| s.bytes_read).sum(),
        bytes_written: stages.iter().map(|s| s.bytes_written).sum(),
        bytes_written_raw: stages.iter().map(|s| s.bytes_written_raw).sum(),
        attempts_bytes_read: stages.iter().map(|s| s.attempts_bytes_read).sum(),
        attempts_bytes_written: stages.iter().map(|s| s.attempts_bytes_written).sum(),
        breakdown: StageBreakdown::default(),
        peak_memory_bytes: stages
            .iter()
            .map(|s| s.peak_memory_bytes)
            .max()
            .unwrap_or(0),
    };
    let rows: Vec<Vec<String>> = stages.iter().map(row).collect();
    print_table(&HEADERS, &rows, &row(&total), out)
}

const BREAKDOWN_HEADERS: [&str; 9] = [
    "stage",
    "task s",
    "compute",
    "encode",
    "decode",
    "storage",
    "other",
    "invocation",
    "orchestration",
];

/// Writes where each stage's time went (seconds, docs/ARCHITECTURE.md section 14): the tasks'
/// own time and its parts (compute, encode, decode, storage, and `other`, the rest of the
/// tasks' time: bookkeeping), all summed over the stage's tasks, then the invocation overhead
/// (summed over tasks) and the orchestration time (wall-clock, no task running), with a total
/// row of the column sums.
pub fn print_breakdown(stages: &[StageReport], out: &mut dyn Write) -> io::Result<()> {
    let cells = |name: &str, b: &StageBreakdown| {
        let other = (b.task - b.compute - b.encode - b.decode - b.storage).max(0.0);
        let mut r = vec![name.to_owned()];
        for v in [
            b.task,
            b.compute,
            b.encode,
            b.decode,
            b.storage,
            other,
            b.invocation,
            b.orchestration,
        ] {
            r.push(format!("{v:.2}"));
        }
        r
    };
    // Not `sum()`: an empty f64 sum is -0.0, which prints as `-0.00`.
    let sum = |f: fn(&StageBreakdown) -> f64| stages.iter().fold(0.0, |t, s| t + f(&s.breakdown));
    let total = StageBreakdown {
        task: sum(|b| b.task),
        compute: sum(|b| b.compute),
        encode: sum(|b| b.encode),
        decode: sum(|b| b.decode),
        storage: sum(|b| b.storage),
        invocation: sum(|b| b.invocation),
        orchestration: sum(|b| b.orchestration),
    };
    let rows: Vec<Vec<String>> = stages
        .iter()
        .map(|s| cells(&s.name, &s.breakdown))
        .collect();
    print_table(&BREAKDOWN_HEADERS, &rows, &cells("total", &total), out)
}

/// Writes `headers`, `rows`, a rule and `total`, aligned: the first column to the left, the
/// others to the right.
fn print_table(
    headers: &[&str],
    rows: &[Vec<String>],
    total: &[String],
    out: &mut dyn Write,
) -> io::Result<()> {
    let header: Vec<String> = headers.iter().map(|h| (*h).to_owned()).collect();
    let mut widths: Vec<usize> = headers.iter().map(|h| h.len()).collect();
    for r in rows.iter().map(Vec::as_slice).chain([total]) {
        for (w, cell) in widths.iter_mut().zip(r) {
            *w = (*w).max(cell.chars().count());
        }
    }
    let line = |out: &mut dyn Write, cells: &[String]| -> io::Result<()> {
        let mut text = String::new();
        for (i, (cell, w)) in cells.iter().zip(&widths).enumerate() {
            if i == 0 {
                text.push_str(&format!("{cell:<w$}"));
            } else {
                text.push_str(&format!("  {cell:>w$}"));
            }
        }
        writeln!(out, "{}", text.trim_end())
    };
    line(out, &header)?;
    for r in rows {
        line(out, r)?;
    }
    let rule: usize = widths.iter().sum::<usize>() + 2 * (widths.len() - 1);
    writeln!(out, "{}", "-".repeat(rule))?;
    line(out, total)
}

fn row(s: &StageReport) -> Vec<String> {
    let mb = |bytes: u64| format!("{:.2}", bytes as f64 / 1e6);
    let ratio = if s.bytes_written == 0 {
        "-".to_owned()
    } else {
        format!(
            "{:.2}x",
            s.bytes_written_raw as f64 / s.bytes_written as f64
        )
    };
    vec![
        s.name.clone(),
        s.tasks.to_string(),
        s.attempts.to_string(),
        format!("{:.2}", s.seconds),
        mb(s.bytes_read),
        mb(s.bytes_written),
        ratio,
        match s.peak_memory_bytes {
            0 => "-".to_owned(),
            peak => format!("{:.1}", peak as f64 / f64::from(1 << 20)),
        },
    ]
}
