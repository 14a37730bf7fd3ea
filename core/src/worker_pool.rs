//! The one in-process worker pool: indexed work items on scoped threads, each thread with its
//! own state (a cache, scratch buffers, or nothing), results handed back to the calling thread.
//! Used by the monolithic renderer (one item per image row) and meant for the pipeline driver
//! (one item per task, one split cache per worker).

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Mutex, PoisonError, mpsc};

/// Cores this process may use (at least 1): the default thread and worker count everywhere.
pub fn available_cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// Runs `work(&mut state, item)` for the items `0..items` on one scoped thread per element of
/// `states` (no more threads than items; extra states are not used) and passes each result to
/// `collect(item, result)` on the calling thread, in the order the items finish.
///
/// Guarantees:
/// - Without errors, every item runs exactly once and `collect` sees every result; the call
///   returns when all threads have finished. Which thread runs an item (so which state it
///   gets) is up to scheduling: make results independent of the state's history (a cache may
///   only change speed), and combine them by item index or with an order-independent
///   operation (integer sums), and the outcome does not depend on the thread count.
/// - The first error (in time) stops the pool: no thread starts another item, items already
///   running finish, results that arrived are still collected, and that error is returned.
///   Later errors of items that were already running are dropped.
/// - A panic in `work` is propagated to the caller once all threads have stopped.
///
/// Panics if `states` is empty while `items > 0` (there would be no thread to run them).
pub fn run_indexed<S, T, E>(
    states: impl IntoIterator<Item = S>,
    items: usize,
    work: impl Fn(&mut S, usize) -> Result<T, E> + Sync,
    mut collect: impl FnMut(usize, T),
) -> Result<(), E>
where
    S: Send,
    T: Send,
    E: Send,
{
    let mut states = states.into_iter().take(items).peekable();
    assert!(
        items == 0 || states.peek().is_some(),
        "a worker pool needs at least one state (thread) to run {items} items"
    );
    let next = AtomicUsize::new(0);
    let failed = AtomicBool::new(false);
    let first_error: Mutex<Option<E>> = Mutex::new(None);
    let (tx, rx) = mpsc::channel();
    std::thread::scope(|scope| {
        for mut state in states {
            let tx = tx.clone();
            let (next, failed, first_error, work) = (&next, &failed, &first_error, &work);
            scope.spawn(move || {
                while !failed.load(Ordering::Relaxed) {
                    let item = next.fetch_add(1, Ordering::Relaxed);
                    if item >= items {
                        break;
                    }
                    match work(&mut state, item) {
                        Ok(result) => {
                            if tx.send((item, result)).is_err() {
                                break;
                            }
                        }
                        Err(e) => {
                            failed.store(true, Ordering::Relaxed);
                            first_error
                                .lock()
                                .unwrap_or_else(PoisonError::into_inner)
                                .get_or_insert(e);
                        }
                    }
                }
            });
        }
        drop(tx);
        for (item, result) in rx {
            collect(item, result);
        }
    });
    match first_error
        .into_inner()
        .unwrap_or_else(PoisonError::into_inner)
    {
        Some(e) => Err(e),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_item_runs_once_and_results_reach_the_caller() {
        for threads in [1, 2, 5, 40] {
            let mut seen = vec![0u32; 30];
            let result: Result<(), ()> = run_indexed(
                vec![(); threads],
                seen.len(),
                |(), item| Ok(item * 10),
                |item, value| {
                    assert_eq!(value, item * 10);
                    seen[item] += 1;
                },
            );
            assert_eq!(result, Ok(()));
            assert_eq!(seen, vec![1; 30], "{threads} threads");
        }
    }

    #[test]
    fn each_thread_owns_its_state() {
        // States count the items their thread ran: together, every item once.
        let states: Vec<Mutex<u32>> = (0..3).map(|_| Mutex::new(0)).collect();
        let result: Result<(), ()> = run_indexed(
            states.iter(),
            100,
            |count, _| {
                *count.lock().unwrap() += 1;
                Ok(())
            },
            |_, ()| {},
        );
        assert_eq!(result, Ok(()));
        let total: u32 = states.iter().map(|c| *c.lock().unwrap()).sum();
        assert_eq!(total, 100);
        // Mutable per-thread state needs no lock.
        let result: Result<(), ()> = run_indexed(
            vec![Vec::new(); 2],
            10,
            |scratch: &mut Vec<usize>, item| {
                scratch.push(item);
                Ok(scratch.len())
            },
            |_, len| assert!((1..=10).contains(&len)),
        );
        assert_eq!(result, Ok(()));
    }

    #[test]
    fn the_first_error_stops_the_pool_and_is_returned() {
        // One thread: items run in order, so exactly items 0..=3 start and 0..3 are collected.
        let started = AtomicUsize::new(0);
        let mut collected = Vec::new();
        let result = run_indexed(
            [()],
            100,
            |(), item| {
                started.fetch_add(1, Ordering::Relaxed);
                if item == 3 { Err(item) } else { Ok(item) }
            },
            |_, item| collected.push(item),
        );
        assert_eq!(result, Err(3));
        assert_eq!(started.into_inner(), 4);
        assert_eq!(collected, [0, 1, 2]);
        // Two threads, slow items: the other thread stops after the item it is running (all
        // 2000 would take 0.4 s), and only one error comes back even if several items fail.
        let started = AtomicUsize::new(0);
        let result = run_indexed(
            [(), ()],
            2000,
            |(), item| {
                started.fetch_add(1, Ordering::Relaxed);
                std::thread::sleep(std::time::Duration::from_micros(200));
                if item >= 5 { Err(item) } else { Ok(()) }
            },
            |_, ()| {},
        );
        assert!(matches!(result, Err(5..)), "{result:?}");
        assert!(started.into_inner() < 2000);
    }

    #[test]
    fn no_items_need_no_threads() {
        let result: Result<(), ()> = run_indexed(Vec::<()>::new(), 0, |(), _| Ok(()), |_, ()| {});
        assert_eq!(result, Ok(()));
    }

    #[test]
    #[should_panic(expected = "at least one state")]
    fn items_without_threads_are_a_bug() {
        let _: Result<(), ()> = run_indexed(Vec::<()>::new(), 1, |(), _| Ok(()), |_, ()| {});
    }
}
