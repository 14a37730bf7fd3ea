//! The allocator and its counters: the only `unsafe` code of the crate.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering::Relaxed};

/// A global allocator that delegates to [`System`] and counts the bytes of every block it hands
/// out and takes back, per thread and per process (see the [crate documentation](crate)).
#[derive(Debug, Clone, Copy, Default)]
pub struct TaskAlloc;

/// Set by the first allocation through [`TaskAlloc`]: it is the global allocator.
static INSTALLED: AtomicBool = AtomicBool::new(false);
/// Bytes live in the process. Every block freed was counted when allocated (the global
/// allocator sees every allocation of the process), so this never goes below zero.
static PROCESS_LIVE: AtomicU64 = AtomicU64::new(0);
/// The highest `PROCESS_LIVE` since start or the last reset.
static PROCESS_PEAK: AtomicU64 = AtomicU64::new(0);

thread_local! {
    /// Bytes allocated on this thread minus bytes freed on it: negative after freeing blocks
    /// other threads allocated.
    static LIVE: Cell<i64> = const { Cell::new(0) };
    /// The highest `LIVE` since the innermost running `measure` scope started.
    static HIGH: Cell<i64> = const { Cell::new(0) };
}

/// Whether [`TaskAlloc`] is the global allocator (it has served an allocation).
pub(crate) fn is_installed() -> bool {
    INSTALLED.load(Relaxed)
}

/// This thread's live count.
pub(crate) fn thread_live() -> &'static std::thread::LocalKey<Cell<i64>> {
    &LIVE
}

/// This thread's high-water mark.
pub(crate) fn thread_high() -> &'static std::thread::LocalKey<Cell<i64>> {
    &HIGH
}

pub(crate) fn process_live() -> u64 {
    PROCESS_LIVE.load(Relaxed)
}

pub(crate) fn process_peak() -> u64 {
    PROCESS_PEAK.load(Relaxed)
}

pub(crate) fn reset_process_peak() {
    PROCESS_PEAK.store(PROCESS_LIVE.load(Relaxed), Relaxed);
}

/// Counts `size` new bytes on this thread and in the process.
fn grow(size: usize) {
    if !INSTALLED.load(Relaxed) {
        INSTALLED.store(true, Relaxed);
    }
    let size = size as u64;
    let now = PROCESS_LIVE.fetch_add(size, Relaxed) + size;
    PROCESS_PEAK.fetch_max(now, Relaxed);
    // `try_with`: never fails for these constant, destructor-free keys, but an allocator must
    // not panic.
    let _ = LIVE.try_with(|live| {
        let now = live.get().saturating_add(size as i64);
        live.set(now);
        let _ = HIGH.try_with(|high| {
            if now > high.get() {
                high.set(now);
            }
        });
    });
}

/// Counts `size` bytes freed on this thread and in the process.
fn shrink(size: usize) {
    PROCESS_LIVE.fetch_sub(size as u64, Relaxed);
    let _ = LIVE.try_with(|live| live.set(live.get().saturating_sub(size as i64)));
}

// SAFETY: every method forwards its arguments unchanged to `System`, which upholds the
// `GlobalAlloc` contract; the counting around it touches only atomics and constant-initialised
// thread-locals without destructors, so it neither allocates nor unwinds.
unsafe impl GlobalAlloc for TaskAlloc {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's guarantees for `layout` are passed on unchanged.
        let ptr = unsafe { System.alloc(layout) };
        if !ptr.is_null() {
            grow(layout.size());
        }
        ptr
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        // SAFETY: as in `alloc`.
        let ptr = unsafe { System.alloc_zeroed(layout) };
        if !ptr.is_null() {
            grow(layout.size());
        }
        ptr
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from this allocator, hence from `System`, with `layout`.
        unsafe { System.dealloc(ptr, layout) };
        shrink(layout.size());
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: `ptr` came from `System` with `layout`; the caller vouches for `new_size`.
        let moved = unsafe { System.realloc(ptr, layout, new_size) };
        if moved == ptr {
            // Resized in place: only the difference was ever live.
            if new_size >= layout.size() {
                grow(new_size - layout.size());
            } else {
                shrink(layout.size() - new_size);
            }
        } else if !moved.is_null() {
            // Moved: both blocks were live while the contents were copied.
            grow(new_size);
            shrink(layout.size());
        }
        moved
    }
}
