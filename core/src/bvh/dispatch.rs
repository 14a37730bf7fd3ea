//! Which SIMD width the ray kernels use: chosen once per process from the host's instruction
//! sets, so one binary serves every x86-64 host (Lambda's included) and aarch64.
//!
//! - [`KernelWidth::Four`]: 4-wide tests everywhere (SSE4.1 on x86-64, NEON on aarch64).
//! - [`KernelWidth::Eight`]: x86-64 hosts with AVX2. Ray packets then test each triangle of a
//!   leaf against eight of their rays at once (`leaf_lanes.rs`).
//! - [`KernelWidth::Sixteen`]: x86-64 hosts with AVX-512F (and AVX2): the same against all
//!   sixteen rays of a packet at once where enough of them are active to pay for it, else
//!   eight. The default on hosts of the Ice Lake generation on (see [`preferred`]).
//!
//! Every width gives the same bits (`lanes.rs`), so the choice changes speed only. The
//! environment variable `HORT_SIMD_WIDTH=4` (or `8`, `16`) overrides the detection for a
//! process (to compare speeds, or to check bytes); tests force each width with
//! [`force_kernel_width`].

use std::sync::OnceLock;
use std::sync::atomic::{AtomicU8, Ordering};

/// The SIMD width of the ray kernels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KernelWidth {
    /// 4-wide tests: SSE4.1 on x86-64, NEON on aarch64.
    Four,
    /// Leaf tests of ray packets eight rays at a time (x86-64 with AVX2).
    Eight,
    /// Leaf tests of ray packets sixteen rays at a time (x86-64 with AVX-512F and AVX2).
    Sixteen,
}

impl KernelWidth {
    /// The lanes of the width: 4, 8 or 16.
    pub fn lanes(self) -> u8 {
        match self {
            KernelWidth::Four => 4,
            KernelWidth::Eight => 8,
            KernelWidth::Sixteen => 16,
        }
    }
}

/// The environment variable that overrides the detected width: `4`, `8` or `16`.
pub const WIDTH_VARIABLE: &str = "HORT_SIMD_WIDTH";

/// 0: no forced width; else the forced width's lane count.
static FORCED: AtomicU8 = AtomicU8::new(0);

/// The widths this host can run, narrowest first.
pub fn available_kernel_widths() -> Vec<KernelWidth> {
    let mut widths = vec![KernelWidth::Four];
    if has_avx2() {
        widths.push(KernelWidth::Eight);
        if has_avx512f() {
            widths.push(KernelWidth::Sixteen);
        }
    }
    widths
}

/// The width the kernels use now: a forced width, else the detected one.
#[inline]
pub fn kernel_width() -> KernelWidth {
    match FORCED.load(Ordering::Relaxed) {
        4 => KernelWidth::Four,
        8 => KernelWidth::Eight,
        16 => KernelWidth::Sixteen,
        _ => *DETECTED.get_or_init(detect),
    }
}

/// Forces `width` for the whole process (`None` returns to detection). For tests of each
/// path and for benchmarks; the answers are the same at every width. Panics when the host
/// cannot run `width`.
pub fn force_kernel_width(width: Option<KernelWidth>) {
    if let Some(w) = width {
        assert!(
            available_kernel_widths().contains(&w),
            "this host cannot run the {w:?} kernels"
        );
    }
    let lanes = width.map_or(0, KernelWidth::lanes);
    FORCED.store(lanes, Ordering::Relaxed);
}

static DETECTED: OnceLock<KernelWidth> = OnceLock::new();

/// The width a process uses unless told otherwise: `Sixteen` where the host has AVX-512F and
/// its 512-bit instructions cost no clock speed (see [`has_cheap_avx512`]), else `Eight` where
/// it has AVX2, else `Four`. Measured on an AVX-512 Xeon (Sapphire Rapids), one pinned core,
/// the same image bits: whole renders at `Sixteen` took 0.90 to 0.99 of `Eight`'s time (bundled
/// scenes at 4 to 256 spp, a 300k-triangle mesh at 4 spp), and the same within the noise on a
/// 1M-triangle mesh at 1 and 16 spp (`docs/perf/time-per-sample.md`, "Sixteen lanes by
/// default").
fn preferred(available: &[KernelWidth]) -> KernelWidth {
    if available.contains(&KernelWidth::Sixteen) && has_cheap_avx512() {
        KernelWidth::Sixteen
    } else if available.contains(&KernelWidth::Eight) {
        KernelWidth::Eight
    } else {
        KernelWidth::Four
    }
}

fn detect() -> KernelWidth {
    let available = available_kernel_widths();
    let preferred = preferred(&available);
    match std::env::var(WIDTH_VARIABLE) {
        Err(_) => preferred,
        Ok(asked) => match available.iter().find(|w| w.lanes().to_string() == asked) {
            Some(&w) => w,
            None => {
                let names: Vec<String> = available.iter().map(|w| w.lanes().to_string()).collect();
                eprintln!(
                    "warning: {WIDTH_VARIABLE}={asked:?} is not a width this host runs ({}); using {preferred:?}",
                    names.join(", ")
                );
                preferred
            }
        },
    }
}

fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

fn has_avx512f() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx512f")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Whether the host's AVX-512 is of the Ice Lake generation or later (Intel from Ice Lake,
/// AMD from Zen 4), told by AVX-512 VPOPCNTDQ, which those have and the Skylake-SP and Cascade
/// Lake generations lack. Those first AVX-512 Xeons lower a core's clock for a while after
/// 512-bit floating-point instructions (their "licence" levels), which slows the scalar rest of
/// a sample too; Ice Lake made that penalty small. Only hosts with the later generation's
/// AVX-512 get `Sixteen` by default; `HORT_SIMD_WIDTH=16` still asks for it anywhere.
fn has_cheap_avx512() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx512vpopcntdq")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}
