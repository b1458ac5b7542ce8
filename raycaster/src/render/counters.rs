//! Per-thread work counters and the statistics a frame returns.

use std::time::Duration;

/// Work done by one thread; summed at the end of a frame (no atomics in the loop).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counters {
    /// Rays that hit the volume's box.
    pub rays: u64,
    /// Samples reconstructed (trilinear reads).
    pub samples: u64,
    /// Rays stopped before their last sample (opacity threshold or first hit).
    pub rays_terminated: u64,
    /// Samples not taken because their brick was empty.
    pub samples_skipped_empty: u64,
    /// (ray, brick) visits marched.
    pub brick_visits: u64,
    /// (ray, brick) visits skipped as empty.
    pub brick_visits_skipped: u64,
    /// (tile, brick) tasks not sent because every pixel the brick covers in the
    /// tile had finished: its ray terminated early (global early ray
    /// termination; most of them), hit, or took its last sample before the
    /// brick (parallel renderer; so some are skipped without ERT too).
    pub tasks_skipped_occluded: u64,
    /// (tile, brick) tasks rendered (parallel renderer).
    pub tasks: u64,
    /// Of `samples`, those a SIMD packet kernel marched (the others: the
    /// scalar loop). The only count that depends on the kernel: every kernel
    /// takes the same samples.
    pub samples_in_lanes: u64,
}

impl std::ops::AddAssign for Counters {
    fn add_assign(&mut self, o: Counters) {
        self.rays += o.rays;
        self.samples += o.samples;
        self.rays_terminated += o.rays_terminated;
        self.samples_skipped_empty += o.samples_skipped_empty;
        self.brick_visits += o.brick_visits;
        self.brick_visits_skipped += o.brick_visits_skipped;
        self.tasks_skipped_occluded += o.tasks_skipped_occluded;
        self.tasks += o.tasks;
        self.samples_in_lanes += o.samples_in_lanes;
    }
}

/// What a frame cost.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FrameStats {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Summed work counters.
    pub counters: Counters,
    /// Bricks of the grid.
    pub bricks: u64,
    /// Bricks the transfer function makes transparent.
    pub bricks_transparent: u64,
    /// Render threads used.
    pub threads: u32,
    /// Wall time of the frame.
    pub time: Duration,
    /// The pyramid level the frame sampled (0: full resolution); in a frame of
    /// several levels, the finest (nearest).
    pub level: u32,
    /// The coarsest level the frame sampled (`level` in a frame of one).
    pub coarsest_level: u32,
}

impl FrameStats {
    /// Samples per second of wall time.
    pub fn samples_per_second(&self) -> f64 {
        self.counters.samples as f64 / self.time.as_secs_f64().max(1e-9)
    }
}
