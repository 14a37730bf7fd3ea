//! Memory high-water marks of tasks: [`TaskAlloc`], a global allocator that delegates every
//! request to [`std::alloc::System`] and counts the bytes, and [`measure`], which runs a closure
//! and returns the most bytes its thread held at once above where it started.
//!
//! A binary opts in with
//!
//! ```
//! #[global_allocator]
//! static ALLOCATOR: hort_task_memory::TaskAlloc = hort_task_memory::TaskAlloc;
//!
//! fn main() {
//!     let (v, peak) = hort_task_memory::measure(|| vec![1u8; 1000]);
//!     assert_eq!(peak, Some(1000));
//!     # drop(v);
//! }
//! ```
//!
//! Without that, nothing is counted and [`measure`] and [`process_peak_bytes`] say so (`None`)
//! rather than report zero.
//!
//! # What is counted
//!
//! Bytes are the sizes of the layouts requested from the allocator (what a program asked for,
//! not the allocator's own rounding, headers or fragmentation). Two sets of counters are kept:
//!
//! - **Per thread** (for tasks that share a process, one task per thread): each thread has a
//!   signed count of the bytes allocated on it minus the bytes freed on it, and the highest
//!   value that count reached. A block freed on another thread than the one that allocated it
//!   lowers the freeing thread's count and leaves the allocating thread's as it was: nothing
//!   underflows, wraps or panics, and no thread's count ever includes a block twice. So within a
//!   [`measure`] scope the peak is exact for memory the task allocates and frees on its own
//!   thread; memory it hands to another thread to free stays counted (an over-count, on the safe
//!   side); memory it frees that was allocated before the scope or on another thread lowers the
//!   count from that point on (that memory did leave the process). Allocations made by other
//!   threads on the task's behalf (a thread it spawns, an async runtime's worker threads) are not
//!   counted in the task's scope.
//! - **Per process**: the bytes live in the whole process and their highest value since the
//!   last [`reset_process_peak`]. For a process that runs one task at a time (a Lambda
//!   function's container) this counts everything the task's threads allocate.
//!
//! Counting costs two relaxed atomic operations and two thread-local updates per allocation and
//! one atomic and one thread-local update per free. The thread-local counters are
//! constant-initialised and have no destructor, so the allocator never allocates itself and
//! works during thread start-up and teardown.

#![deny(unsafe_op_in_unsafe_fn)]
#![warn(missing_docs)]

mod counters;

pub use counters::TaskAlloc;

use counters::{is_installed, thread_high, thread_live};

/// Runs `f` on this thread and returns its result with the highest number of bytes this thread
/// held at once during `f`, above what it held when `f` started (0 when it never went above),
/// as described in the [crate documentation](crate). `None` when [`TaskAlloc`] is not the
/// global allocator. Scopes nest: an inner scope's peak is also seen by the outer one, and a
/// panic in `f` leaves the outer scope's peak correct.
pub fn measure<T>(f: impl FnOnce() -> T) -> (T, Option<u64>) {
    /// Restores the outer scope's high-water mark, raised to this scope's, even on a panic.
    struct Scope {
        outer_high: i64,
    }
    impl Drop for Scope {
        fn drop(&mut self) {
            let inner = thread_high().get();
            thread_high().set(inner.max(self.outer_high));
        }
    }
    let base = thread_live().get();
    let scope = Scope {
        outer_high: thread_high().replace(base),
    };
    let out = f();
    let peak = thread_high().get().saturating_sub(base).max(0);
    drop(scope);
    (out, is_installed().then_some(peak.unsigned_abs()))
}

/// Bytes allocated and not yet freed in the whole process; `None` when [`TaskAlloc`] is not
/// the global allocator.
pub fn process_live_bytes() -> Option<u64> {
    is_installed().then(counters::process_live)
}

/// The highest [`process_live_bytes`] since the process started or the last
/// [`reset_process_peak`]; `None` when [`TaskAlloc`] is not the global allocator.
pub fn process_peak_bytes() -> Option<u64> {
    is_installed().then(counters::process_peak)
}

/// Starts a new process-wide high-water mark at the bytes live now (for a process that runs one
/// task at a time: call it as a task starts, read [`process_peak_bytes`] as it ends).
pub fn reset_process_peak() {
    counters::reset_process_peak();
}

#[cfg(test)]
mod tests {
    use super::*;

    /// This crate's unit tests run on the default allocator: nothing is counted, and the
    /// functions say so instead of reporting zero.
    #[test]
    fn without_the_allocator_nothing_is_reported() {
        let (v, peak) = measure(|| vec![7u8; 1 << 16]);
        assert_eq!(v.len(), 1 << 16);
        assert_eq!(peak, None);
        assert_eq!(process_live_bytes(), None);
        assert_eq!(process_peak_bytes(), None);
    }
}
