//! Where one thread's render time goes, phase by phase: the monolithic renderer's row loop
//! reports the end of each phase of each batch to a [`PhaseTimer`]. The renderer itself passes
//! [`NoTimer`], whose laps compile to nothing; `hort bench samples` passes [`PhaseTimes`],
//! which reads the clock at each lap.
//!
//! Timing never changes what is computed: a render with [`PhaseTimes`] has the same bits as
//! one without (`render::tests::phase_timed_render_is_the_render`).

use std::time::Instant;

/// A phase of rendering a batch of camera samples, in the order the row loop runs them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Phase {
    /// Between batches: the row loop's own work (batch bounds, buffers).
    Loop,
    /// Sample positions and camera rays (`Camera::pixels_rays`).
    CameraRays,
    /// Closest-hit traversal of the camera rays (`Bvh::closest_hits`).
    ClosestHits,
    /// Shading: surface points of the hits and shadow segments towards the lights, then each
    /// sample's sum over its unblocked lights.
    Shading,
    /// Any-hit traversal of the shadow segments (`Bvh::occluded_many`).
    ShadowRays,
    /// Pixel means and ray counts (`PixelSum`), the hit buffer.
    Accumulation,
}

impl Phase {
    /// Every phase, in [`Phase`] order (`ALL[p as usize] == p`).
    pub const ALL: [Phase; 6] = [
        Phase::Loop,
        Phase::CameraRays,
        Phase::ClosestHits,
        Phase::Shading,
        Phase::ShadowRays,
        Phase::Accumulation,
    ];

    /// The phase's name in tables.
    pub fn name(self) -> &'static str {
        match self {
            Phase::Loop => "loop",
            Phase::CameraRays => "camera rays",
            Phase::ClosestHits => "closest hits",
            Phase::Shading => "shading",
            Phase::ShadowRays => "shadow rays",
            Phase::Accumulation => "accumulation",
        }
    }
}

/// Receives the end of each phase.
pub trait PhaseTimer {
    /// The time since the previous lap (or since the timer was made) was spent in `phase`.
    fn lap(&mut self, phase: Phase);
}

/// The renderer's timer: no clock reads at all.
pub struct NoTimer;

impl PhaseTimer for NoTimer {
    #[inline(always)]
    fn lap(&mut self, _: Phase) {}
}

/// Nanoseconds per phase, from a monotonic clock read at every lap.
#[derive(Clone, Debug)]
pub struct PhaseTimes {
    last: Instant,
    /// Nanoseconds spent in each phase, indexed by `Phase as usize`.
    pub nanos: [u64; 6],
}

impl PhaseTimes {
    /// A timer whose first lap counts from now.
    pub fn start() -> Self {
        PhaseTimes {
            last: Instant::now(),
            nanos: [0; 6],
        }
    }

    /// Nanoseconds of `phase`.
    pub fn of(&self, phase: Phase) -> u64 {
        self.nanos[phase as usize]
    }
}

impl PhaseTimer for PhaseTimes {
    #[inline]
    fn lap(&mut self, phase: Phase) {
        let now = Instant::now();
        self.nanos[phase as usize] += now.duration_since(self.last).as_nanos() as u64;
        self.last = now;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn all_is_in_declaration_order() {
        for (i, p) in Phase::ALL.iter().enumerate() {
            assert_eq!(*p as usize, i, "{}", p.name());
        }
    }

    /// Laps charge the time since the previous lap to the named phase, and nothing else.
    #[test]
    fn laps_charge_the_elapsed_time_to_their_phase() {
        let mut t = PhaseTimes::start();
        std::thread::sleep(std::time::Duration::from_millis(20));
        t.lap(Phase::ShadowRays);
        t.lap(Phase::CameraRays);
        assert!(t.of(Phase::ShadowRays) >= 20_000_000, "{:?}", t.nanos);
        assert!(t.of(Phase::CameraRays) < 20_000_000, "{:?}", t.nanos);
        let others: u64 = [
            Phase::Loop,
            Phase::ClosestHits,
            Phase::Shading,
            Phase::Accumulation,
        ]
        .iter()
        .map(|&p| t.of(p))
        .sum();
        assert_eq!(others, 0);
    }
}
