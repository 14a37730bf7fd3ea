//! [`measure`] with [`TaskAlloc`] installed: exact peaks per thread, several threads at once,
//! blocks freed on another thread, nesting.

use hort_task_memory::{TaskAlloc, measure};
use std::sync::{Barrier, Mutex};

#[global_allocator]
static ALLOCATOR: TaskAlloc = TaskAlloc;

const MIB: usize = 1 << 20;

/// A block of `n` bytes that the optimiser cannot remove.
fn block(n: usize) -> Vec<u8> {
    std::hint::black_box(Vec::with_capacity(n))
}

#[test]
fn a_scope_reports_exactly_its_highest_allocation() {
    let ((), peak) = measure(|| {
        let a = block(MIB);
        let b = block(3 * MIB);
        drop(a);
        drop(b);
        let c = block(2 * MIB);
        drop(c);
    });
    assert_eq!(peak, Some(4 * MIB as u64), "a and b were live together");
    let ((), peak) = measure(|| {});
    assert_eq!(peak, Some(0));
}

#[test]
fn a_grown_vector_counts_both_blocks_while_it_moves() {
    let (v, peak) = measure(|| {
        let mut v = block(MIB);
        v.reserve_exact(4 * MIB);
        v
    });
    let peak = peak.unwrap();
    // In place: 4 MiB; moved: 1 + 4 MiB at the copy.
    assert!(
        peak == 4 * MIB as u64 || peak == 5 * MIB as u64,
        "peak {peak}"
    );
    assert!(v.capacity() >= 4 * MIB);
}

#[test]
fn concurrent_threads_each_see_only_their_own_allocations() {
    let threads = 4;
    let barrier = Barrier::new(threads);
    let peaks: Vec<Option<u64>> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..threads)
            .map(|i| {
                let barrier = &barrier;
                s.spawn(move || {
                    measure(|| {
                        let held = block((i + 1) * MIB);
                        // Every thread holds its block while the others hold theirs.
                        barrier.wait();
                        drop(held);
                    })
                    .1
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    let expected: Vec<Option<u64>> = (1..=threads).map(|i| Some((i * MIB) as u64)).collect();
    assert_eq!(peaks, expected);
}

#[test]
fn blocks_freed_on_another_thread_neither_underflow_nor_count_twice() {
    let slot: Mutex<Option<Vec<u8>>> = Mutex::new(None);
    // Allocated here and handed over: it stays counted in this scope (the safe side).
    let ((), handed) = measure(|| {
        *slot.lock().unwrap() = Some(block(2 * MIB));
    });
    assert_eq!(handed, Some(2 * MIB as u64));
    // The other thread frees 2 MiB it never allocated, then allocates 1 MiB: its count goes
    // below its start and the 1 MiB never rises above it.
    let (freer, after) = std::thread::scope(|s| {
        s.spawn(|| {
            let ((), freeing) = measure(|| {
                drop(slot.lock().unwrap().take());
                drop(block(MIB));
            });
            let ((), after) = measure(|| drop(block(3 * MIB)));
            (freeing, after)
        })
        .join()
        .unwrap()
    });
    assert_eq!(freer, Some(0));
    assert_eq!(after, Some(3 * MIB as u64), "a later scope starts afresh");
}

#[test]
fn nested_scopes_each_see_their_own_peak() {
    let (inner, outer) = measure(|| {
        let kept = block(MIB);
        let ((), inner) = measure(|| drop(block(2 * MIB)));
        drop(kept);
        inner
    });
    assert_eq!(inner, Some(2 * MIB as u64));
    assert_eq!(
        outer,
        Some(3 * MIB as u64),
        "the inner scope's peak plus what was kept"
    );
}

#[test]
fn a_panicking_inner_scope_still_raises_the_outer_peak() {
    let ((), outer) = measure(|| {
        let result = std::panic::catch_unwind(|| {
            measure(|| {
                let _held = block(5 * MIB);
                panic!("inside");
            })
        });
        assert!(result.is_err());
    });
    assert!(outer.unwrap() >= 5 * MIB as u64, "{outer:?}");
}
