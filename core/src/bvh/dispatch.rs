//! Which SIMD width the ray kernels use: chosen once per process from the host's instruction
//! sets, so one binary serves every x86-64 host (Lambda's included) and aarch64.
//!
//! - [`KernelWidth::Four`]: 4-wide tests everywhere (SSE4.1 on x86-64, NEON on aarch64).
//! - [`KernelWidth::Eight`]: x86-64 hosts with AVX2. Closest-hit packets then test each
//!   triangle of a leaf against eight of their rays at once (`leaf8.rs`).
//!
//! Every width gives the same bits (`lanes.rs`), so the choice changes speed only. The
//! environment variable `HORT_SIMD_WIDTH=4` (or `8`) overrides the detection for a process (to
//! compare speeds, or to check bytes); tests force each width with [`force_kernel_width`].

use std::sync::OnceLock;
use std::sync::atomic::{AtomicU8, Ordering};

/// The SIMD width of the ray kernels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KernelWidth {
    /// 4-wide tests: SSE4.1 on x86-64, NEON on aarch64.
    Four,
    /// 8-wide leaf tests of closest-hit packets (x86-64 with AVX2).
    Eight,
}

/// The environment variable that overrides the detected width: `4` or `8`.
pub const WIDTH_VARIABLE: &str = "HORT_SIMD_WIDTH";

/// 0: no forced width; else the forced width's lane count.
static FORCED: AtomicU8 = AtomicU8::new(0);

/// The widths this host can run, narrowest first.
pub fn available_kernel_widths() -> Vec<KernelWidth> {
    let mut widths = vec![KernelWidth::Four];
    if has_avx2() {
        widths.push(KernelWidth::Eight);
    }
    widths
}

/// The width the kernels use now: a forced width, else the detected one.
#[inline]
pub fn kernel_width() -> KernelWidth {
    match FORCED.load(Ordering::Relaxed) {
        4 => KernelWidth::Four,
        8 => KernelWidth::Eight,
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
    let lanes = match width {
        None => 0,
        Some(KernelWidth::Four) => 4,
        Some(KernelWidth::Eight) => 8,
    };
    FORCED.store(lanes, Ordering::Relaxed);
}

static DETECTED: OnceLock<KernelWidth> = OnceLock::new();

fn detect() -> KernelWidth {
    let widest = *available_kernel_widths()
        .last()
        .expect("Four is always there");
    match std::env::var(WIDTH_VARIABLE).as_deref() {
        Ok("4") => KernelWidth::Four,
        Ok("8") if widest == KernelWidth::Eight => KernelWidth::Eight,
        Ok(other) => {
            eprintln!(
                "warning: {WIDTH_VARIABLE}={other:?} is not a width this host runs (4{}); using {widest:?}",
                if widest == KernelWidth::Eight {
                    " or 8"
                } else {
                    ""
                }
            );
            widest
        }
        Err(_) => widest,
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
