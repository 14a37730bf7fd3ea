//! The documented AWS price model behind the report's `cost_usd` (docs/ARCHITECTURE.md: dollars
//! per frame from GB-seconds, requests and S3 operations).
//!
//! # Prices
//! List prices for us-east-1, read 2026-11 from the AWS pricing pages for Lambda
//! (<https://aws.amazon.com/lambda/pricing/>), S3 (<https://aws.amazon.com/s3/pricing/>) and
//! Step Functions (<https://aws.amazon.com/step-functions/pricing/>).
//! They all live in the constants below; change them there, with the date.
//!
//! | what | price | billing unit |
//! |---|---|---|
//! | Lambda compute, arm64 | $0.0000133334 per GB-s | each invocation rounded up to 1 ms; GB = memory MB / 1024 |
//! | Lambda compute, x86_64 | $0.0000166667 per GB-s | same |
//! | Lambda requests | $0.20 per million | every invocation, every attempt |
//! | S3 PUT, COPY, POST, LIST | $0.005 per 1,000 | every request sent, failed ones too |
//! | S3 GET, HEAD (and all other non-DELETE reads) | $0.0004 per 1,000 | same |
//! | S3 Standard storage | $0.023 per GB-month | byte-seconds; GB = 2^30 bytes; month = 730 h |
//! | Step Functions Standard | $0.025 per 1,000 state transitions | retries count |
//! | Step Functions Express requests | $1.00 per million | one per execution started |
//! | Step Functions Express duration | $0.00001667 per GB-s | each execution rounded up to 100 ms; memory in 64 MB chunks |
//!
//! # How our state machine is billed (`infra/statemachine.asl.json`)
//! The job is one STANDARD execution: Plan (Task) → Choice states → per stage a Distributed Map,
//! its lost step (a Plan function Task) and a Choice → Combine (Task) → Done (Succeed). Each Map
//! runs one EXPRESS child execution per item; the child runs one Lambda Task whose retries
//! happen inside the child, and the Map writes its results to S3 (`ResultWriter`: a few PUTs,
//! counted with the S3 requests where the caller counts them). So:
//! - Standard transitions ([`standard_transitions_for`]): one per state entered in the parent,
//!   the terminal state included, plus one per retry of a parent state, plus one per child
//!   execution a Distributed Map starts (the Step Functions guide, "Transitions": "you're charged
//!   one state transition for each child workflow execution that the Distributed Map state
//!   starts"). The states *inside* an EXPRESS child are not Standard transitions.
//! - Express: every child execution is one request, billed for its whole duration (retry
//!   back-off included) rounded up to 100 ms, at 64 MB: the billed memory is a whole number of
//!   64 MB chunks driven by definition and payload size, and our child definition (one Task) and
//!   payload (one item, well under 256 KiB) stay in the first chunk.
//! - Lambda: every attempt is one request and one billed duration, init included (custom
//!   runtimes such as `provided.al2023` have their init phase billed).
//! - S3: the requests the handlers send, plus the ItemReader `GetObject` of each Distributed Map
//!   (billed to the account like any GET); the caller counts them.
//!
//! # What is not counted
//! Free tiers (Lambda 1M requests and 400,000 GB-s, Step Functions 4,000 transitions, S3) are
//! ignored: this is the marginal cost of one job. Express duration is priced at its first tier
//! (first 1,000 GB-hours a month; later tiers are cheaper, so this is an upper bound). Not
//! counted: data transfer (S3 and Lambda in one Region exchange data for free), S3 DELETE (free),
//! Lambda ephemeral storage above the free 512 MB, provisioned concurrency, CloudWatch Logs
//! ingestion and storage, KMS, request-signing retries the SDK hides from the caller unless the
//! caller counts them, and storage of anything kept after the job (inputs, final image).
//! S3 storage of intermediate objects *is* counted, through [`CostInputs::s3_byte_seconds`]: it is
//! usually negligible (10 GiB held for one hour costs 10 × $0.023 / 730 ≈ $0.0003), but it costs
//! nothing to show it.

use serde::{Deserialize, Serialize};

/// Month the prices below were read.
pub const PRICES_AS_OF: &str = "2026-11";
/// Region the prices below are for.
pub const PRICE_REGION: &str = "us-east-1";

/// Lambda compute, arm64 (Graviton), USD per GB-second.
pub const LAMBDA_USD_PER_GB_S_ARM64: f64 = 0.000_013_333_4;
/// Lambda compute, x86_64, USD per GB-second.
pub const LAMBDA_USD_PER_GB_S_X86_64: f64 = 0.000_016_666_7;
/// Lambda requests, USD per million invocations.
pub const LAMBDA_USD_PER_MILLION_REQUESTS: f64 = 0.20;
/// Lambda duration granularity: each invocation is rounded up to a multiple of this.
pub const LAMBDA_BILLING_GRANULARITY_MS: u64 = 1;

/// S3 Standard PUT, COPY, POST and LIST requests, USD per 1,000.
pub const S3_USD_PER_1000_PUT_LIKE: f64 = 0.005;
/// S3 Standard GET, HEAD and other reads, USD per 1,000.
pub const S3_USD_PER_1000_GET_LIKE: f64 = 0.0004;
/// S3 Standard storage, USD per GB-month (first 50 TB tier).
pub const S3_USD_PER_GB_MONTH: f64 = 0.023;
/// Bytes in the GB S3 storage is priced in (AWS bills binary gigabytes).
pub const S3_BYTES_PER_GB: f64 = 1_073_741_824.0;
/// Seconds in the month storage is prorated over (730 hours, the AWS pricing average).
pub const S3_SECONDS_PER_MONTH: f64 = 730.0 * 3600.0;

/// Step Functions Standard, USD per 1,000 state transitions.
pub const SFN_STANDARD_USD_PER_1000_TRANSITIONS: f64 = 0.025;
/// Step Functions Express, USD per million executions started.
pub const SFN_EXPRESS_USD_PER_MILLION_REQUESTS: f64 = 1.00;
/// Step Functions Express duration, USD per GB-second (first 1,000 GB-hours a month).
pub const SFN_EXPRESS_USD_PER_GB_S: f64 = 0.000_016_67;
/// Express duration granularity: each execution is rounded up to a multiple of this.
pub const SFN_EXPRESS_BILLING_GRANULARITY_MS: u64 = 100;
/// Express billed memory: one 64 MB chunk, the minimum and what our one-Task children use.
pub const SFN_EXPRESS_BILLED_MEMORY_MB: u32 = 64;

/// Lambda instruction set architecture; it sets the GB-second price.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Arch {
    /// Graviton (`arm64`), the cheaper GB-second price; the default.
    #[default]
    Arm64,
    /// Intel/AMD (`x86_64`).
    X86_64,
}

impl Arch {
    /// Lambda compute price for this architecture, USD per GB-second.
    pub fn lambda_usd_per_gb_s(self) -> f64 {
        match self {
            Arch::Arm64 => LAMBDA_USD_PER_GB_S_ARM64,
            Arch::X86_64 => LAMBDA_USD_PER_GB_S_X86_64,
        }
    }
}

/// What one job used. Every Lambda function of the job is assumed to have the same `arch` and
/// `memory_mb`; for functions configured differently, estimate each group and add the totals.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CostInputs {
    /// Architecture of the Lambda functions; sets the GB-second price.
    pub arch: Arch,
    /// Configured Lambda memory, MB (128-10,240 on AWS).
    pub memory_mb: u32,
    /// One entry per Lambda invocation, every attempt included: its duration in ms, init phase
    /// included for cold starts. Lambda's own `Billed Duration` (whole ms) may be passed as is.
    /// The number of entries is the number of Lambda requests.
    pub invocation_ms: Vec<f64>,
    /// S3 PUT, COPY, POST and LIST requests sent, failed ones (e.g. a 412 conditional PUT) too.
    pub s3_put_like: u64,
    /// S3 GET and HEAD requests sent, the Distributed Map ItemReader reads included.
    pub s3_get_like: u64,
    /// Intermediate storage: the sum over objects of bytes × seconds stored. An upper bound is
    /// bytes written × job wall-clock seconds.
    pub s3_byte_seconds: f64,
    /// State transitions of the STANDARD execution; see [`standard_transitions_for`].
    pub standard_transitions: u64,
    /// One entry per EXPRESS child execution: its duration in ms, from start to end (retries
    /// inside it included). The number of entries is the number of Express requests.
    pub express_ms: Vec<f64>,
}

/// Estimated cost in USD, per service line. `total` is the sum of the other fields.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct CostBreakdown {
    /// Lambda GB-seconds.
    pub lambda_compute: f64,
    /// Lambda invocations.
    pub lambda_requests: f64,
    /// S3 PUT-like and GET-like requests.
    pub s3_requests: f64,
    /// S3 storage of intermediate objects, prorated by the second.
    pub s3_storage: f64,
    /// Standard transitions, Express requests and Express duration.
    pub step_functions: f64,
    /// All of the above, USD.
    pub total: f64,
}

/// Billed duration of one run of `ms` milliseconds: rounded up to a whole multiple of
/// `granularity_ms` (0 is taken as 1), at least one granule (a run that happened is never free).
/// NaN and negative durations bill one granule; +infinity saturates at `u64::MAX`.
pub fn billed_ms(ms: f64, granularity_ms: u64) -> u64 {
    let granularity = granularity_ms.max(1);
    // `as` saturates: +inf -> u64::MAX, NaN and negatives -> 0.
    let whole = ms.ceil() as u64;
    whole
        .div_ceil(granularity)
        .max(1)
        .saturating_mul(granularity)
}

/// Sum of [`billed_ms`] over runs: each run is rounded up on its own, then summed.
pub fn total_billed_ms(runs_ms: &[f64], granularity_ms: u64) -> u64 {
    runs_ms.iter().fold(0u64, |sum, &ms| {
        sum.saturating_add(billed_ms(ms, granularity_ms))
    })
}

/// GB-seconds of `billed_ms` milliseconds at `memory_mb` (GB = 1,024 MB, as AWS bills).
pub fn gb_seconds(memory_mb: u32, billed_ms: u64) -> f64 {
    billed_ms as f64 * f64::from(memory_mb) / (1024.0 * 1000.0)
}

/// State transitions of one STANDARD execution of our machine, as Step Functions bills them:
/// - one per top-level state entered (`states_entered`: Task, Map, Choice, Pass, and the
///   terminal Succeed or Fail state; a state entered again, as in a rerun loop, counts again);
/// - one per retry of a top-level state (`retries_outside_maps`: Plan, Combine and the lost
///   steps; our Map states have no Retry of their own);
/// - one per child execution a Distributed Map starts (`child_executions`, summed over the
///   Maps). The states inside an EXPRESS child, and the retries of its Task, are not Standard
///   transitions: they are billed as the child's Express duration and as Lambda invocations.
///
/// A fused job without retries or lost items: `standard_transitions_for(8, items, 0)`
/// ([`clean_path_states`]).
pub fn standard_transitions_for(
    states_entered: u64,
    child_executions: u64,
    retries_outside_maps: u64,
) -> u64 {
    states_entered + child_executions + retries_outside_maps
}

/// The top-level states a job without failures, lost items or a second round enters in
/// `infra/statemachine.asl.json` (a test walks the definition to check it): `Plan`,
/// `ChooseScene`, `ChooseMode`; per Map stage its Map, its lost step and its Check (`map_stages`
/// of them: 1 fused, 5 staged, 3 staged without shadows); staged jobs add `ChooseShadows` and
/// `ChooseRefine`; then `Combine` and `Done`. A scene split by tasks adds the `Partition` and
/// `Build` stages (3 states each) and the `Cut` and `PlanFromParts` steps.
pub fn clean_path_states(map_stages: u64, staged: bool, split_by_tasks: bool) -> u64 {
    const PLAN_AND_CHOICES: u64 = 3;
    const PER_MAP_STAGE: u64 = 3;
    const COMBINE_AND_DONE: u64 = 2;
    let staged_choices = if staged { 2 } else { 0 };
    let by_tasks = if split_by_tasks {
        2 * PER_MAP_STAGE + 2
    } else {
        0
    };
    PLAN_AND_CHOICES + PER_MAP_STAGE * map_stages + staged_choices + COMBINE_AND_DONE + by_tasks
}

/// The price model: [`CostInputs`] to dollars. Empty inputs cost exactly zero.
pub fn estimate(inputs: &CostInputs) -> CostBreakdown {
    let lambda_billed = total_billed_ms(&inputs.invocation_ms, LAMBDA_BILLING_GRANULARITY_MS);
    let lambda_compute =
        gb_seconds(inputs.memory_mb, lambda_billed) * inputs.arch.lambda_usd_per_gb_s();
    let lambda_requests =
        inputs.invocation_ms.len() as f64 * LAMBDA_USD_PER_MILLION_REQUESTS / 1_000_000.0;

    let s3_requests = inputs.s3_put_like as f64 * S3_USD_PER_1000_PUT_LIKE / 1000.0
        + inputs.s3_get_like as f64 * S3_USD_PER_1000_GET_LIKE / 1000.0;
    let s3_storage = inputs.s3_byte_seconds.max(0.0) / S3_BYTES_PER_GB / S3_SECONDS_PER_MONTH
        * S3_USD_PER_GB_MONTH;

    let express_billed = total_billed_ms(&inputs.express_ms, SFN_EXPRESS_BILLING_GRANULARITY_MS);
    let step_functions = inputs.standard_transitions as f64 * SFN_STANDARD_USD_PER_1000_TRANSITIONS
        / 1000.0
        + inputs.express_ms.len() as f64 * SFN_EXPRESS_USD_PER_MILLION_REQUESTS / 1_000_000.0
        + gb_seconds(SFN_EXPRESS_BILLED_MEMORY_MB, express_billed) * SFN_EXPRESS_USD_PER_GB_S;

    CostBreakdown {
        lambda_compute,
        lambda_requests,
        s3_requests,
        s3_storage,
        step_functions,
        total: lambda_compute + lambda_requests + s3_requests + s3_storage + step_functions,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Equal to within 1e-12 relative: the expected values below are exact decimals worked by
    /// hand, the code computes them in binary floating point.
    fn close(got: f64, want: f64) -> bool {
        (got - want).abs() <= 1e-12 * want.abs().max(1e-9)
    }

    macro_rules! assert_close {
        ($got:expr, $want:expr) => {{
            let (got, want) = ($got, $want);
            assert!(
                close(got, want),
                "{} = {got:e}, want {want:e}",
                stringify!($got)
            );
        }};
    }

    #[test]
    fn lambda_rounds_each_invocation_up_to_the_ms() {
        assert_eq!(billed_ms(1000.2, 1), 1001);
        assert_eq!(billed_ms(1000.0, 1), 1000);
        assert_eq!(billed_ms(0.3, 1), 1);
        // Each run is rounded before summing: 3 x 0.4 ms bills 3 ms, not 2.
        assert_eq!(total_billed_ms(&[0.4, 0.4, 0.4], 1), 3);
        // Lambda's own whole-ms Billed Duration passes through unchanged.
        assert_eq!(total_billed_ms(&[13.0, 250.0], 1), 263);
    }

    #[test]
    fn express_rounds_each_execution_up_to_100_ms() {
        assert_eq!(billed_ms(100.0, 100), 100);
        assert_eq!(billed_ms(100.1, 100), 200);
        assert_eq!(billed_ms(1.0, 100), 100);
        assert_eq!(billed_ms(1050.0, 100), 1100);
        assert_eq!(total_billed_ms(&[50.0, 150.0], 100), 300);
    }

    #[test]
    fn a_run_is_never_free_and_odd_durations_do_not_panic() {
        assert_eq!(billed_ms(0.0, 1), 1);
        assert_eq!(billed_ms(-5.0, 100), 100);
        assert_eq!(billed_ms(f64::NAN, 1), 1);
        assert_eq!(billed_ms(7.5, 0), 8);
        assert_eq!(billed_ms(f64::INFINITY, 100), u64::MAX);
        assert_eq!(total_billed_ms(&[f64::INFINITY, 1.0], 1), u64::MAX);
    }

    #[test]
    fn zero_inputs_cost_zero() {
        let cost = estimate(&CostInputs::default());
        assert_eq!(cost, CostBreakdown::default());
        assert_eq!(cost.total, 0.0);
    }

    #[test]
    fn lambda_arm64_by_hand() {
        // 1,000 invocations of 1,000.2 ms at 2,048 MB: 1,001 ms each, 1,001 s at 2 GB = 2,002 GB-s.
        // 2,002 x 0.0000133334 = 0.0266934668; 1,000 x 0.20 / 1e6 = 0.0002.
        let inputs = CostInputs {
            memory_mb: 2048,
            invocation_ms: vec![1000.2; 1000],
            ..CostInputs::default()
        };
        assert_close!(gb_seconds(2048, 1_001_000), 2002.0);
        let cost = estimate(&inputs);
        assert_close!(cost.lambda_compute, 0.026_693_466_8);
        assert_close!(cost.lambda_requests, 0.000_2);
        assert_close!(cost.total, 0.026_893_466_8);
        assert_eq!(
            cost.s3_requests + cost.s3_storage + cost.step_functions,
            0.0
        );
    }

    #[test]
    fn x86_64_costs_a_quarter_more_per_gb_s() {
        let arm = CostInputs {
            arch: Arch::Arm64,
            memory_mb: 2048,
            invocation_ms: vec![1000.2; 1000],
            ..CostInputs::default()
        };
        let x86 = CostInputs {
            arch: Arch::X86_64,
            ..arm.clone()
        };
        let (arm, x86) = (estimate(&arm), estimate(&x86));
        // 2,002 x 0.0000166667 = 0.0333667334.
        assert_close!(x86.lambda_compute, 0.033_366_733_4);
        assert_eq!(arm.lambda_requests, x86.lambda_requests);
        assert_close!(
            x86.lambda_compute / arm.lambda_compute,
            0.0000166667 / 0.0000133334
        );
        assert!(x86.total > arm.total);
    }

    #[test]
    fn s3_by_hand() {
        // 10,000 PUT-like x 0.005 / 1,000 = 0.05; 40,000 GET-like x 0.0004 / 1,000 = 0.016.
        // 1 GiB held for 730 h is one GB-month: 0.023.
        let cost = estimate(&CostInputs {
            s3_put_like: 10_000,
            s3_get_like: 40_000,
            s3_byte_seconds: 1_073_741_824.0 * 730.0 * 3600.0,
            ..CostInputs::default()
        });
        assert_close!(cost.s3_requests, 0.066);
        assert_close!(cost.s3_storage, 0.023);
        assert_close!(cost.total, 0.089);
        // Negative storage (a caller's bug) is not a refund.
        let cost = estimate(&CostInputs {
            s3_byte_seconds: -1.0,
            ..CostInputs::default()
        });
        assert_eq!(cost.total, 0.0);
    }

    #[test]
    fn transitions_of_our_machine() {
        // Fused: Plan, ChooseScene, ChooseMode, Render, RenderLost, RenderCheck, Combine, Done.
        assert_eq!(clean_path_states(1, false, false), 8);
        // Staged: 5 Map stages of 3 states, ChooseShadows and ChooseRefine.
        assert_eq!(clean_path_states(5, true, false), 22);
        assert_eq!(clean_path_states(3, true, false), 16);
        assert_eq!(clean_path_states(5, true, true), 30);
        assert_eq!(standard_transitions_for(22, 1000, 0), 1022);
        // Two Plan retries and one Combine retry.
        assert_eq!(standard_transitions_for(22, 1000, 3), 1025);
    }

    #[test]
    fn step_functions_by_hand() {
        // Standard: 1,008 transitions x 0.025 / 1,000 = 0.0252.
        // Express: 1,000 requests x 1 / 1e6 = 0.001; 1,000 x 1,050 ms bills 1,100 ms each,
        // 1,100 s at 64 MB = 0.0625 GB -> 68.75 GB-s x 0.00001667 = 0.0011460625.
        let cost = estimate(&CostInputs {
            standard_transitions: standard_transitions_for(8, 1000, 0),
            express_ms: vec![1050.0; 1000],
            ..CostInputs::default()
        });
        assert_close!(gb_seconds(64, 1_100_000), 68.75);
        assert_close!(cost.step_functions, 0.0252 + 0.001 + 0.001_146_062_5);
        assert_close!(cost.total, 0.027_346_062_5);
    }

    #[test]
    fn every_line_by_hand() {
        let cost = estimate(&CostInputs {
            arch: Arch::X86_64,
            memory_mb: 1769,
            invocation_ms: vec![12.5, 900.0, 30_000.01],
            s3_put_like: 123,
            s3_get_like: 4567,
            s3_byte_seconds: 5.0e12,
            standard_transitions: 11,
            express_ms: vec![950.0, 31_000.0],
        });
        // Lambda: 13 + 900 + 30,001 = 30,914 ms at 1,769 MB = 30.914 x 1,769 / 1,024
        // = 53.405142578125 GB-s, x $0.0000166667 = $0.0008900874898068359375.
        assert_close!(cost.lambda_compute, 0.000_890_087_489_806_836);
        // 3 requests x $0.20 / 1e6.
        assert_close!(cost.lambda_requests, 0.000_000_6);
        // 123 x $0.005 / 1,000 + 4,567 x $0.0004 / 1,000 = 0.000615 + 0.0018268.
        assert_close!(cost.s3_requests, 0.002_441_8);
        // 5e12 byte-s / 2^30 / (730 x 3,600 s) = 0.00177192270665045 GB-months, x $0.023.
        assert_close!(cost.s3_storage, 0.000_040_754_222_252_960_4);
        // 11 transitions x $0.025 / 1,000 = 0.000275; 2 Express requests x $1 / 1e6 = 0.000002;
        // 950 ms bills 1,000 and 31,000 bills 31,000: 32 s at 64 MB = 2 GB-s x $0.00001667
        // = 0.00003334.
        assert_close!(cost.step_functions, 0.000_310_34);
        assert_close!(cost.total, 0.003_683_581_712_059_796_4);
        let sum = cost.lambda_compute
            + cost.lambda_requests
            + cost.s3_requests
            + cost.s3_storage
            + cost.step_functions;
        assert_eq!(cost.total, sum);
    }

    #[test]
    fn prices_are_the_documented_ones() {
        // The price table of the module documentation, us-east-1, 2026-11.
        assert_eq!(LAMBDA_USD_PER_GB_S_ARM64, 0.000_013_333_4);
        assert_eq!(LAMBDA_USD_PER_GB_S_X86_64, 0.000_016_666_7);
        assert_eq!(LAMBDA_USD_PER_MILLION_REQUESTS, 0.20);
        assert_eq!(LAMBDA_BILLING_GRANULARITY_MS, 1);
        assert_eq!(S3_USD_PER_1000_PUT_LIKE, 0.005);
        assert_eq!(S3_USD_PER_1000_GET_LIKE, 0.0004);
        assert_eq!(S3_USD_PER_GB_MONTH, 0.023);
        assert_eq!(S3_BYTES_PER_GB, 1_073_741_824.0);
        assert_eq!(S3_SECONDS_PER_MONTH, 2_628_000.0);
        assert_eq!(SFN_STANDARD_USD_PER_1000_TRANSITIONS, 0.025);
        assert_eq!(SFN_EXPRESS_USD_PER_MILLION_REQUESTS, 1.0);
        assert_eq!(SFN_EXPRESS_USD_PER_GB_S, 0.000_016_67);
        assert_eq!(SFN_EXPRESS_BILLING_GRANULARITY_MS, 100);
        assert_eq!(SFN_EXPRESS_BILLED_MEMORY_MB, 64);
        assert_eq!((PRICES_AS_OF, PRICE_REGION), ("2026-11", "us-east-1"));
    }

    #[test]
    fn serializes_with_stable_names() {
        let json = serde_json::to_value(estimate(&CostInputs::default())).unwrap();
        for key in [
            "lambda_compute",
            "lambda_requests",
            "s3_requests",
            "s3_storage",
            "step_functions",
            "total",
        ] {
            assert!(json.get(key).is_some(), "{key}");
        }
        assert_eq!(serde_json::to_value(Arch::X86_64).unwrap(), "x86_64");
        assert_eq!(serde_json::to_value(Arch::Arm64).unwrap(), "arm64");
    }
}
