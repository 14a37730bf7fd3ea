//! The process-wide counters with [`TaskAlloc`] installed. One test in its own binary: nothing
//! else allocates or frees while it reads them.

use hort_task_memory::{TaskAlloc, process_live_bytes, process_peak_bytes, reset_process_peak};

#[global_allocator]
static ALLOCATOR: TaskAlloc = TaskAlloc;

const MIB: u64 = 1 << 20;

#[test]
fn the_process_counters_see_every_thread() {
    let before = process_live_bytes().unwrap();
    reset_process_peak();
    assert_eq!(process_peak_bytes(), Some(before));
    // Allocated on another thread, freed here.
    let held = std::thread::spawn(|| std::hint::black_box(Vec::<u8>::with_capacity(8 << 20)))
        .join()
        .unwrap();
    let live = process_live_bytes().unwrap();
    assert!(live >= before + 8 * MIB, "{live} after {before}");
    drop(held);
    let after = process_live_bytes().unwrap();
    assert_eq!(
        live - after,
        8 * MIB,
        "the block, freed on another thread than its own"
    );
    assert!(process_peak_bytes().unwrap() >= before + 8 * MIB);
    reset_process_peak();
    assert_eq!(process_peak_bytes(), Some(after));
}
