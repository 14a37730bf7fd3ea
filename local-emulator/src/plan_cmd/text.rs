//! The text form of `hort plan`'s output: the plan, its stages at the chosen function count,
//! the sweep, and the notes, in fixed-width tables.

use super::PlanOutput;
use hort_core::plural::count;
use hort_core::predict::{Projection, Target, usd};
use std::fmt::Write;

/// The whole text `hort plan` prints, ending in a newline.
pub fn render(o: &PlanOutput) -> String {
    let mut t = String::new();
    let _ = writeln!(
        t,
        "plan: {}, {}x{}, {} spp, {}, {}",
        o.scene,
        o.width,
        o.height,
        o.spp,
        count(o.triangles, "triangle"),
        count(o.lights, "light"),
    );
    let _ = writeln!(t, "mode: {} ({})", o.mode, o.mode_reason);
    let _ = writeln!(
        t,
        "splits: {} ({}), spans: {}, tasks: {}",
        o.splits,
        match o.split_mode {
            hort_core::pipeline::SplitMode::Naive => "naive",
            hort_core::pipeline::SplitMode::Spatial => "spatial",
        },
        o.spans,
        o.tasks
    );
    let c = &o.calibration;
    let _ = writeln!(
        t,
        "calibration: BVH of {} triangles {:.2} ms, {} rays {:.2} ms on one core; reference \
         machine {:.2} ms and {:.2} ms: speed {:.2}",
        c.triangles,
        c.build_ms,
        c.rays,
        c.trace_ms,
        c.reference_build_ms,
        c.reference_trace_ms,
        c.speed
    );
    let _ = writeln!(t, "target: {}", target_line(o));
    let _ = writeln!(
        t,
        "\nstages at {} function{}{}:",
        o.functions,
        if o.functions == 1 { "" } else { "s" },
        if o.functions_is_best {
            " (the best of the sweep)"
        } else {
            ""
        }
    );
    let _ = writeln!(
        t,
        "{:<15} {:>7} {:>10} {:>8} {:>8} {:>9} {:>9}  bound",
        "stage", "tasks", "bytes", "task s", "stage s", "S3 GET", "S3 PUT"
    );
    for s in &o.stages {
        let _ = writeln!(
            t,
            "{:<15} {:>7} {:>10} {:>8.3} {:>8.3} {:>9} {:>9}  {}",
            s.name,
            s.tasks,
            bytes(s.bytes),
            s.task_seconds,
            s.seconds,
            s.s3_gets,
            s.s3_puts,
            s.bound
        );
    }
    let _ = writeln!(t, "total: {}", summary(&o.chosen));
    if o.frames > 1 {
        let n = f64::from(o.frames);
        let _ = writeln!(
            t,
            "per frame: {:.2} s, {} ({} frames in one job, the scene prepared once)",
            o.chosen.seconds / n,
            usd(o.chosen.dollars / n),
            o.frames
        );
    }
    let _ = writeln!(
        t,
        "cost: predicted from the model above, not measured (`hort render` prices a run's task \
         times on this machine and its requests, so the two differ)"
    );
    let _ = writeln!(t, "\nsweep:");
    let _ = writeln!(
        t,
        "{:>9} {:>9} {:>11} {:>9} {:>9} {:>11} {:>12}",
        "functions", "seconds", "function-s", "S3 GET", "S3 PUT", "transitions", "dollars"
    );
    for p in &o.projection {
        let _ = writeln!(
            t,
            "{:>9} {:>9.2} {:>11.2} {:>9} {:>9} {:>11} {:>12}",
            p.functions,
            p.seconds,
            p.function_seconds,
            p.s3_gets,
            p.s3_puts,
            p.transitions,
            usd(p.dollars)
        );
    }
    for note in &o.chosen.notes {
        let _ = writeln!(t, "note: {note}");
    }
    t
}

fn target_line(o: &PlanOutput) -> String {
    let retries = if o.fail_rate > 0.0 {
        format!(
            ", failure rate {} ({:.3} attempts per task)",
            o.fail_rate,
            1.0 / (1.0 - o.fail_rate)
        )
    } else {
        String::new()
    };
    match o.target {
        Target::Aws { memory_mb, arch } => format!(
            "AWS Lambda {} {} MB ({:.2} vCPU), a vCPU as fast as one reference core{retries}",
            arch_name(arch),
            memory_mb,
            (f64::from(memory_mb) / 1769.0).min(1.0)
        ),
        Target::Emulator {
            cores,
            s3_latency_ms,
            ..
        } => format!(
            "the local emulator on {cores} cores at speed {:.2}, S3 latency {s3_latency_ms} ms \
             added per request{retries}",
            o.speed
        ),
    }
}

fn arch_name(arch: hort_core::cost::Arch) -> &'static str {
    match arch {
        hort_core::cost::Arch::Arm64 => "arm64",
        hort_core::cost::Arch::X86_64 => "x86_64",
    }
}

fn summary(p: &Projection) -> String {
    format!(
        "{:.2} s, {:.2} function-seconds, {} S3 GET and {} PUT, {} Step Functions transitions, \
         {}",
        p.seconds,
        p.function_seconds,
        p.s3_gets,
        p.s3_puts,
        p.transitions,
        usd(p.dollars)
    )
}

/// Bytes with a binary unit, three significant digits.
fn bytes(n: u64) -> String {
    const UNITS: [&str; 5] = ["B", "KiB", "MiB", "GiB", "TiB"];
    let mut x = n as f64;
    let mut unit = 0;
    while x >= 1024.0 && unit + 1 < UNITS.len() {
        x /= 1024.0;
        unit += 1;
    }
    if unit == 0 {
        format!("{n} B")
    } else {
        format!("{x:.1} {}", UNITS[unit])
    }
}
