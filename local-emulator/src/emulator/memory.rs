//! The function memory budget, enforced as Lambda enforces it: a Worker attempt whose measured
//! memory, plus the runtime allowance the plan's memory model assumes, is over the job's
//! `memory_mb` fails with [`OUT_OF_MEMORY`], which the state machine never retries (the same
//! task would use the same memory again). See docs/ARCHITECTURE.md, "Task memory".

use asl_interpreter::TaskFailure;
use hort_core::pipeline::RUNTIME_BYTES;
use hort_core::stage::Stage;

/// The error name of an attempt over its memory budget: Lambda's for a function that ran out of
/// memory. No `Retry` of `infra/statemachine.asl.json` names it, and the Map children do not
/// catch it, so the job fails at its first such attempt.
pub const OUT_OF_MEMORY: &str = "Runtime.OutOfMemory";

/// The memory a Worker invocation may use.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryBudget {
    /// The function's memory, MB of 2^20 bytes (the job's `memory_mb`).
    pub mb: u32,
}

impl MemoryBudget {
    /// [`OUT_OF_MEMORY`] naming the task, what it used and the budget, when `measured` bytes
    /// (what the task held at its peak, its warm cache included) plus [`RUNTIME_BYTES`] (the
    /// runtime, code and stacks the measurement cannot see, as the plan's model assumes) exceed
    /// the budget; `None` when they fit.
    pub fn check(
        self,
        stage: Stage,
        task: u32,
        attempt: u64,
        measured: u64,
    ) -> Option<TaskFailure> {
        let used = measured.saturating_add(RUNTIME_BYTES);
        (used > u64::from(self.mb) << 20).then(|| {
            TaskFailure::new(
                OUT_OF_MEMORY,
                format!(
                    "task {stage}/{task}/{attempt} used {} MB of its {} MB memory budget ({} MB \
                     runtime allowance + {} MB measured)",
                    mb(used),
                    thousands(u64::from(self.mb)),
                    mb(RUNTIME_BYTES),
                    mb(measured),
                ),
            )
        })
    }
}

/// `bytes` in MB of 2^20 bytes, one decimal, thousands separated: `1,234.5`.
fn mb(bytes: u64) -> String {
    let tenths = (bytes as u128 * 10 + (1 << 19)) >> 20;
    format!("{}.{}", thousands((tenths / 10) as u64), tenths % 10)
}

/// `n` with a comma every three digits: `1,234,567`.
fn thousands(n: u64) -> String {
    let digits = n.to_string();
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_task_over_its_budget_fails_with_one_line_naming_the_figures() {
        let budget = MemoryBudget { mb: 1024 };
        let fits = (1024 << 20) - RUNTIME_BYTES;
        assert_eq!(budget.check(Stage::CastMap, 3, 1, fits), None);
        let failure = budget.check(Stage::CastMap, 3, 1, fits + 1).unwrap();
        assert_eq!(failure.error, "Runtime.OutOfMemory");
        assert_eq!(
            failure.cause,
            "task cast-map/3/1 used 1,024.0 MB of its 1,024 MB memory budget (96.0 MB runtime \
             allowance + 928.0 MB measured)"
        );
        let failure = MemoryBudget { mb: 10_240 }
            .check(Stage::Render, 0, 0, 12_000 << 20)
            .unwrap();
        assert_eq!(
            failure.cause,
            "task render/0/0 used 12,096.0 MB of its 10,240 MB memory budget (96.0 MB runtime \
             allowance + 12,000.0 MB measured)"
        );
    }

    #[test]
    fn megabytes_round_to_a_tenth() {
        assert_eq!(mb(0), "0.0");
        assert_eq!(mb((1 << 20) / 20 - 1), "0.0");
        assert_eq!(mb((1 << 20) / 20 + 1), "0.1");
        assert_eq!(mb(1_234 << 20), "1,234.0");
        assert_eq!(thousands(999), "999");
        assert_eq!(thousands(1_000), "1,000");
        assert_eq!(thousands(12_345_678), "12,345,678");
    }
}
