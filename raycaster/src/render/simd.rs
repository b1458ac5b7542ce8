//! The instruction sets the SIMD kernel runs on, detected once per process.
//!
//! [`SimdLevel::Scalar`] is the reference: one sample at a time through the
//! generic marching loop. Every other level marches the samples of each ray a
//! few at a time in SIMD lanes with the same arithmetic, compiled for that
//! instruction set: eight at a time with hardware gathers on AVX2 and AVX-512
//! ([`super::gather`]), four at a time through the cell cache on SSE4.1 and
//! NEON ([`super::packet`]).

use std::fmt;
use std::sync::OnceLock;

/// How the marching kernel runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum SimdLevel {
    /// One sample at a time: the reference kernel.
    Scalar,
    /// The SIMD kernel compiled for SSE4.1 (x86-64).
    Sse41,
    /// The SIMD kernel compiled for AVX2 and FMA (x86-64).
    Avx2,
    /// The SIMD kernel compiled for AVX-512 (F, VL, BW; x86-64).
    Avx512,
    /// The SIMD kernel compiled for NEON (aarch64).
    Neon,
}

impl SimdLevel {
    /// Every level, in the order `--help` lists them.
    pub const ALL: [SimdLevel; 5] = [
        SimdLevel::Scalar,
        SimdLevel::Sse41,
        SimdLevel::Avx2,
        SimdLevel::Avx512,
        SimdLevel::Neon,
    ];

    /// The level's name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            SimdLevel::Scalar => "scalar",
            SimdLevel::Sse41 => "sse4.1",
            SimdLevel::Avx2 => "avx2",
            SimdLevel::Avx512 => "avx512",
            SimdLevel::Neon => "neon",
        }
    }

    /// The level named `name` (as [`Self::name`] spells it).
    pub fn parse(name: &str) -> Option<SimdLevel> {
        Self::ALL.into_iter().find(|l| l.name() == name)
    }

    /// Whether this machine can run the level.
    pub fn is_available(self) -> bool {
        available().contains(&self)
    }

    /// Whether this level has hardware gathers (AVX2, AVX-512): the levels
    /// whose kernels gather a sample's voxels, so that a sample costs little
    /// beside its ray (the DVR, value and gradient kernels; docs/benchmarks.md,
    /// section 5).
    pub fn has_gathers(self) -> bool {
        matches!(self, SimdLevel::Avx2 | SimdLevel::Avx512)
    }

    /// The widest level this machine runs (detected once per process).
    pub fn widest() -> SimdLevel {
        *available().last().expect("scalar is always available")
    }

    /// The level a frame uses unless told otherwise
    /// ([`super::RenderSettings::simd`] `None`): AVX2 where this CPU has it,
    /// else [`SimdLevel::Scalar`].
    ///
    /// On AVX2, DVR with a 1D, not pre-integrated transfer function runs the
    /// kernel with hardware gathers (`render/gather.rs`): on this project's
    /// 2-core VM 1.6–2.3× the scalar kernel's samples per second unshaded,
    /// 1.2–1.6× shaded (docs/benchmarks.md, section 5). The modes that read
    /// only their samples' values (maximum, average, X-ray, first hit,
    /// Sabella's) and two-level scenes take their values from the same
    /// gathers (`render/gather_values.rs`: average, X-ray and Sabella's 1.8×
    /// faster than before it, maximum 1.04×, first hit the same, two-level
    /// scenes 1.08–1.14×, 1.10× with shaded DVR objects of one function and
    /// the gradients gathered too: `render/gather_gradients.rs`); importance, context-preserving and silhouette
    /// frames and DVR with a 2D function their values and gradients
    /// (`render/gather_gradients.rs`, 1.10–1.28× at step 0.5). Every other
    /// frame (pre-integrated DVR, a two-level scene of shaded DVR objects
    /// whose functions have different domains) takes the scalar kernel whatever the level (its compositor
    /// declines `Compositor::march_packets`, per task). The sequential
    /// renderer takes the scalar kernel under `None`. Every frame is the
    /// same whichever level renders it.
    pub fn automatic() -> SimdLevel {
        if SimdLevel::Avx2.is_available() {
            SimdLevel::Avx2
        } else {
            SimdLevel::Scalar
        }
    }
}

impl fmt::Display for SimdLevel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The levels this machine runs, slowest first (`Scalar` always).
pub fn available() -> &'static [SimdLevel] {
    static LEVELS: OnceLock<Vec<SimdLevel>> = OnceLock::new();
    LEVELS.get_or_init(detect)
}

#[cfg(target_arch = "x86_64")]
fn detect() -> Vec<SimdLevel> {
    let mut levels = vec![SimdLevel::Scalar];
    if is_x86_feature_detected!("sse4.1") {
        levels.push(SimdLevel::Sse41);
    }
    if is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma") {
        levels.push(SimdLevel::Avx2);
        if is_x86_feature_detected!("avx512f")
            && is_x86_feature_detected!("avx512vl")
            && is_x86_feature_detected!("avx512bw")
        {
            levels.push(SimdLevel::Avx512);
        }
    }
    levels
}

#[cfg(target_arch = "aarch64")]
fn detect() -> Vec<SimdLevel> {
    // NEON is part of every aarch64 target Rust supports.
    vec![SimdLevel::Scalar, SimdLevel::Neon]
}

#[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
fn detect() -> Vec<SimdLevel> {
    vec![SimdLevel::Scalar]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_scalar_is_always_there() {
        for level in SimdLevel::ALL {
            assert_eq!(SimdLevel::parse(level.name()), Some(level));
        }
        assert_eq!(SimdLevel::parse("avx3"), None);
        assert_eq!(available()[0], SimdLevel::Scalar);
        assert!(SimdLevel::Scalar.is_available());
        assert!(available().contains(&SimdLevel::widest()));
        assert!(SimdLevel::automatic().is_available());
    }

    /// The kernel tests compare every available level against the scalar
    /// kernel: on aarch64 (`.ci/aarch64`, under qemu) that must include NEON.
    #[test]
    fn each_architecture_lists_its_simd_level() {
        if cfg!(target_arch = "aarch64") {
            assert_eq!(available(), &[SimdLevel::Scalar, SimdLevel::Neon]);
        } else if cfg!(target_arch = "x86_64") {
            assert!(!SimdLevel::Neon.is_available());
        } else {
            assert_eq!(available(), &[SimdLevel::Scalar]);
        }
    }
}
