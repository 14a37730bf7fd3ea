//! Function concurrency slots, the emulator's model of Lambda's concurrency limit.
//!
//! A slot is held for as long as an invocation really runs. When a Task times out, the state
//! machine moves on but the invocation keeps its slot until the function returns, as a Lambda
//! environment stays busy after Step Functions gave up on it.

use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::time::Duration;

/// How often a waiter re-checks its stop condition.
const POLL: Duration = Duration::from_millis(5);

/// A counting semaphore of invocation slots.
#[derive(Debug)]
pub struct Slots {
    free: Mutex<usize>,
    freed: Condvar,
}

/// One held slot; dropping it frees the slot.
#[derive(Debug)]
pub struct SlotGuard {
    slots: Arc<Slots>,
}

impl Slots {
    /// `count` free slots (at least one).
    pub fn new(count: usize) -> Arc<Slots> {
        Arc::new(Slots {
            free: Mutex::new(count.max(1)),
            freed: Condvar::new(),
        })
    }

    fn lock(&self) -> MutexGuard<'_, usize> {
        self.free.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Waits for a free slot; `None` as soon as `stop()` returns true.
    pub fn acquire(self: &Arc<Self>, stop: impl Fn() -> bool) -> Option<SlotGuard> {
        let mut free = self.lock();
        loop {
            if stop() {
                return None;
            }
            if *free > 0 {
                *free -= 1;
                return Some(SlotGuard {
                    slots: Arc::clone(self),
                });
            }
            free = self
                .freed
                .wait_timeout(free, POLL)
                .unwrap_or_else(|p| p.into_inner())
                .0;
        }
    }
}

impl Drop for SlotGuard {
    fn drop(&mut self) {
        *self.slots.lock() += 1;
        self.slots.freed.notify_one();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    #[test]
    fn never_more_holders_than_slots_and_stop_wins() {
        let slots = Slots::new(2);
        let held = AtomicUsize::new(0);
        let peak = AtomicUsize::new(0);
        std::thread::scope(|s| {
            for _ in 0..6 {
                s.spawn(|| {
                    for _ in 0..20 {
                        let _g = slots.acquire(|| false).unwrap();
                        let now = held.fetch_add(1, Ordering::SeqCst) + 1;
                        peak.fetch_max(now, Ordering::SeqCst);
                        std::thread::yield_now();
                        held.fetch_sub(1, Ordering::SeqCst);
                    }
                });
            }
        });
        assert!((1..=2).contains(&peak.load(Ordering::SeqCst)));
        // Both slots can be held at once; a third waiter gives up when told to, and gets a
        // slot when one is freed.
        let a = slots.acquire(|| false).unwrap();
        let _b = slots.acquire(|| false).unwrap();
        assert!(slots.acquire(|| true).is_none());
        std::thread::scope(|s| {
            let waiter = s.spawn(|| slots.acquire(|| false).is_some());
            drop(a);
            assert!(waiter.join().unwrap());
        });
    }
}
