//! The allocator of the AFL++ binaries: the system allocator, but an allocation over
//! [`LIMIT`] aborts, which AFL++ reports as a crash. So an input that makes the code under test
//! allocate from an absurd size it read is a finding, not a slow run. (AFL++'s own `-m` limit
//! caps address space, which these binaries need more of.)

use std::alloc::{GlobalAlloc, Layout, System};

/// Largest single allocation, bytes: 256 MiB, far above what any input under 1 MiB needs.
const LIMIT: usize = 256 << 20;

/// See the module documentation.
pub struct Capped;

fn check(size: usize) {
    if size > LIMIT {
        eprintln!("allocation of {size} bytes (over {LIMIT})");
        std::process::abort();
    }
}

// SAFETY: every call is forwarded to `System` with the same arguments, after a size check.
unsafe impl GlobalAlloc for Capped {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        check(layout.size());
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        check(layout.size());
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        check(new_size);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}
