//! Benchmark cases of the raycaster renderers, defined by one options type.
//!
//! A [`BenchCase`] names everything a benchmarked frame depends on: the volume
//! (scene, size, u8/u16, linear/bricked, RAM/mapped — generated into a cache
//! directory when missing), ERT/ESS, the renderer (sequential, or the parallel one
//! with its threads and tile size), the brick side, the camera preset, the step, the
//! mode and the image size. The criterion benches (`benches/`) are groups built from
//! the lists below, grouped like the reference thesis's tables; `raycaster bench`
//! sweeps grids of the same type.
//!
//! Run with `cargo bench -p raycaster-benches`; `cargo test -p raycaster-benches
//! --benches` runs every benchmark once on small volumes (quick mode, as CI does;
//! `RAYCASTER_BENCH_QUICK=1 cargo bench` is quick with criterion's statistics).

mod case;
mod volumes;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use anyhow::Result;
use raycaster::render::{Mode, SimdLevel};
use raycaster::volume::{Access, Layout, SampleType, Volume};

pub use case::{
    BenchCase, Optimisations, PreparedCase, View, cores, default_cache_dir, parse_access,
    parse_layout, parse_sample_type, quick_mode,
};
pub use volumes::{SceneSpec, VolumeSource, VolumeSpec, sample_type_name};

/// Volume side and image side of the criterion groups: full and quick.
fn sizes(quick: bool) -> (u32, [u32; 2]) {
    if quick {
        (48, [64, 64])
    } else {
        (256, [256, 256])
    }
}

/// The thesis's single-thread optimisation table: the sequential renderer on a
/// `shapes` volume with none / ERT / ESS / both, plus the unshaded loop without
/// optimisations (the kernel's raw samples/s on one core).
pub fn optimisation_cases(quick: bool) -> Vec<BenchCase> {
    let (n, image) = sizes(quick);
    let base = BenchCase {
        volume: VolumeSpec::shapes(n),
        threads: None,
        image,
        ..BenchCase::default()
    };
    let mut cases: Vec<BenchCase> = Optimisations::ALL
        .into_iter()
        .map(|optimisations| BenchCase {
            optimisations,
            ..base.clone()
        })
        .collect();
    cases.push(BenchCase {
        optimisations: Optimisations::None,
        shading: false,
        ..base
    });
    cases
}

/// Memory kinds: RAM vs mapped × u8 vs u16 × linear vs bricked (side 16), one
/// thread (sequential renderer), ERT + ESS.
pub fn memory_cases(quick: bool) -> Vec<BenchCase> {
    let (n, image) = sizes(quick);
    let mut cases = Vec::new();
    for access in [Access::Ram, Access::Mapped] {
        for sample_type in [SampleType::U8, SampleType::U16] {
            for layout in [Layout::Linear, Layout::Bricked { side: 16 }] {
                cases.push(BenchCase {
                    volume: VolumeSpec::shapes(n)
                        .with_access(access)
                        .with_sample_type(sample_type)
                        .with_layout(layout),
                    threads: None,
                    image,
                    ..BenchCase::default()
                });
            }
        }
    }
    cases
}

/// The parallel renderer: render threads (1, 2, and the core count when larger) ×
/// tiles 8/16/32 × bricks 8/16/32, with the sequential renderer per brick side.
pub fn parallel_cases(quick: bool) -> Vec<BenchCase> {
    let (n, image) = sizes(quick);
    let mut threads = vec![1, 2];
    if cores() > 2 {
        threads.push(cores());
    }
    let mut cases = Vec::new();
    for brick in [8, 16, 32] {
        let base = BenchCase {
            volume: VolumeSpec::shapes(n),
            brick: Some(brick),
            image,
            ..BenchCase::default()
        };
        cases.push(BenchCase {
            threads: None,
            ..base.clone()
        });
        for &t in &threads {
            for tile in [8, 16, 32] {
                cases.push(BenchCase {
                    threads: Some(t),
                    tile,
                    ..base.clone()
                });
            }
        }
    }
    cases
}

/// Small frames of the viewer's coarse kind (160×160, the default threads) on a
/// `shapes` volume in RAM: where starting threads per frame shows.
pub fn small_frame_case(quick: bool) -> BenchCase {
    let (n, _) = sizes(quick);
    BenchCase {
        volume: VolumeSpec::shapes(n),
        image: [160, 160],
        ..BenchCase::default()
    }
}

/// The kernel benchmark's cases: shaded DVR at step 0.2 on one render thread, once
/// per marching kernel this machine runs (scalar first, then each packet level);
/// then maximum and average intensity (the value kernel's modes) on the scalar
/// kernel and the widest level.
pub fn kernel_cases(quick: bool) -> Vec<BenchCase> {
    let (n, image) = sizes(quick);
    let case = |mode, level| BenchCase {
        volume: VolumeSpec::shapes(n),
        threads: Some(1),
        step: 0.2,
        image,
        mode,
        simd: Some(level),
        ..BenchCase::default()
    };
    let levels = raycaster::render::simd_levels();
    let widest = SimdLevel::widest();
    let dvr = levels.iter().map(|&level| case(Mode::Dvr, level));
    let others = [Mode::Mip, Mode::Average].into_iter().flat_map(|mode| {
        [SimdLevel::Scalar, widest]
            .into_iter()
            .map(move |level| case(mode, level))
    });
    dvr.chain(others).collect()
}

/// Quality at speed: shaded DVR of a `shapes` volume, the default threads,
/// plain at steps 0.25 and 1 and pre-integrated at steps 1 and 2 (on `shapes`
/// 128³ a pre-integrated step of 1 comes closer to a fine reference than a
/// plain 0.25: docs/benchmarks.md §6). Samples per second compare the kernels;
/// frame times, what the quality costs.
pub fn preintegration_cases(quick: bool) -> Vec<BenchCase> {
    let (n, image) = sizes(quick);
    [(0.25, false), (1.0, false), (1.0, true), (2.0, true)]
        .into_iter()
        .map(|(step, preintegrated)| BenchCase {
            volume: VolumeSpec::shapes(n),
            step,
            preintegrated,
            image,
            ..BenchCase::default()
        })
        .collect()
}

/// The two-level benchmark's plain case (its layered twin adds segments to the
/// settings): the default threads on a `shapes` volume in RAM.
pub fn two_level_case(quick: bool) -> BenchCase {
    let (n, image) = sizes(quick);
    BenchCase {
        volume: VolumeSpec::shapes(n),
        image,
        ..BenchCase::default()
    }
}

/// Opened volumes by [`VolumeSpec::name`], so that cases sharing a volume open
/// (and generate) it once.
#[derive(Debug)]
pub struct Volumes {
    dir: PathBuf,
    open: HashMap<String, Volume>,
}

impl Volumes {
    /// A cache of volumes generated into `dir`.
    pub fn new(dir: impl AsRef<Path>) -> Volumes {
        Volumes {
            dir: dir.as_ref().to_path_buf(),
            open: HashMap::new(),
        }
    }

    /// The volume of `spec`, opened (and generated) on first use.
    pub fn get(&mut self, spec: &VolumeSpec) -> Result<&Volume> {
        let key = spec.name();
        if !self.open.contains_key(&key) {
            let volume = spec.open(&self.dir)?;
            self.open.insert(key.clone(), volume);
        }
        Ok(&self.open[&key])
    }
}

#[cfg(test)]
mod tests {
    use std::collections::HashSet;

    use super::*;

    /// The close view is twice as near as the default: the camera sits at half
    /// its distance from the volume's centre (it sat twice as far).
    #[test]
    fn the_close_view_is_twice_as_near() {
        let volume = raycaster::volume::Volume::from_samples(
            "cube",
            &raycaster::volume::Header::new(
                [8, 8, 8],
                [1.0; 3],
                Layout::Linear,
                SampleType::U8,
                raycaster::volume::Content::Scalar,
                raycaster::volume::Format::Extended,
            ),
            &[0u8; 512],
        )
        .unwrap();
        let centre = raycaster::render::Vec3::splat(3.5);
        let distance =
            |view: View| (view.camera(&volume, [64, 64]).unwrap().position() - centre).length();
        let (default, close) = (distance(View::Default), distance(View::Close));
        assert!(
            (close / default - 0.5).abs() < 1e-4,
            "{close} against {default}"
        );
    }

    fn unique(cases: &[BenchCase]) -> bool {
        let names: HashSet<String> = cases.iter().map(BenchCase::name).collect();
        names.len() == cases.len()
    }

    #[test]
    fn every_group_has_unique_names_and_quick_mode_is_small() {
        // `cargo test` runs without `--bench`: criterion's test mode, hence quick.
        assert!(quick_mode());
        for quick in [false, true] {
            for group in [
                optimisation_cases(quick),
                memory_cases(quick),
                parallel_cases(quick),
                preintegration_cases(quick),
            ] {
                assert!(unique(&group), "{:#?}", group);
                for case in &group {
                    let VolumeSource::Scene(s) = &case.volume.source else {
                        panic!("groups render generated scenes");
                    };
                    assert_eq!(s.dims[0] <= 64, quick, "{}", case.name());
                    assert_eq!(case.image[0] <= 64, quick);
                }
            }
        }
        assert_eq!(optimisation_cases(false).len(), 5);
        assert_eq!(memory_cases(true).len(), 8);
    }

    #[test]
    fn names_show_every_parameter() {
        let case = BenchCase {
            volume: VolumeSpec::shapes(96)
                .with_layout(Layout::Bricked { side: 32 })
                .with_sample_type(SampleType::U16)
                .with_access(Access::Mapped),
            optimisations: Optimisations::Ess,
            threads: Some(2),
            tile: 8,
            brick: Some(16),
            view: View::Close,
            step: 0.2,
            mode: Mode::Mip,
            shading: false,
            preintegrated: false,
            transfer: Some("opaque"),
            image: [70, 50],
            simd: None,
        };
        assert_eq!(
            case.name(),
            "shapes-96-u16-b32-mapped/ess/t2-tile8-brick16/close-step0.2-mip-unshaded-tf-opaque-70x50"
        );
        let packets = BenchCase {
            simd: Some(raycaster::render::SimdLevel::Avx2),
            ..case.clone()
        };
        assert_eq!(
            packets.name(),
            "shapes-96-u16-b32-mapped/ess/t2-tile8-brick16-avx2/close-step0.2-mip-unshaded-tf-opaque-70x50"
        );
        let seq = BenchCase {
            threads: None,
            brick: None,
            ..BenchCase::default()
        };
        assert_eq!(
            seq.name(),
            "shapes-256-u8-linear-ram/both/seq-brick-default/default-step0.5-dvr-256x256"
        );
        let pre = BenchCase {
            step: 1.0,
            preintegrated: true,
            ..seq.clone()
        };
        assert_eq!(
            pre.name(),
            "shapes-256-u8-linear-ram/both/seq-brick-default/default-step1-dvr-preintegrated-256x256"
        );
        assert!(pre.settings().unwrap().preintegrated);
        assert!(!seq.settings().unwrap().preintegrated);
    }

    #[test]
    fn optimisations_parse_and_switch_ert_and_ess() {
        let flags: Vec<(bool, bool)> = Optimisations::ALL.map(|o| (o.ert(), o.ess())).into();
        assert_eq!(
            flags,
            [(false, false), (true, false), (false, true), (true, true)]
        );
        for o in Optimisations::ALL {
            assert_eq!(o.name().parse::<Optimisations>().unwrap(), o);
        }
        assert!("fast".parse::<Optimisations>().is_err());
        let none = BenchCase {
            optimisations: Optimisations::None,
            ..BenchCase::default()
        }
        .settings()
        .unwrap();
        assert_eq!(none.early_termination, None);
        assert!(!none.empty_space_skipping);
        assert!(
            BenchCase {
                step: 0.0,
                ..BenchCase::default()
            }
            .settings()
            .is_err()
        );
        assert!(
            BenchCase {
                transfer: Some("no-such-preset"),
                ..BenchCase::default()
            }
            .settings()
            .is_err()
        );
    }

    #[test]
    fn parsers_accept_the_documented_words() {
        assert_eq!(parse_access("ram").unwrap(), Access::Ram);
        assert_eq!(parse_access("mapped").unwrap(), Access::Mapped);
        assert!(parse_access("disk").is_err());
        assert_eq!(parse_sample_type("u16").unwrap(), SampleType::U16);
        assert!(parse_sample_type("f32").is_err());
        assert_eq!(parse_layout("linear").unwrap(), Layout::Linear);
        assert_eq!(
            parse_layout("bricked:32").unwrap(),
            Layout::Bricked { side: 32 }
        );
        assert!(parse_layout("bricked:1").is_err());
        assert!(parse_layout("bricked:300").is_err());
    }

    /// `prepare` generates a missing scene once, with the stored type and layout
    /// asked for, and every memory kind renders the same samples.
    #[test]
    fn volumes_are_generated_once_and_memory_kinds_agree() {
        let dir = tempfile::tempdir().unwrap();
        let mut volumes = Volumes::new(dir.path());
        let mut samples = HashSet::new();
        for case in memory_cases(true) {
            let case = BenchCase {
                volume: case.volume,
                image: [24, 24],
                ..case
            };
            let volume = volumes.get(&case.volume).unwrap();
            let VolumeSource::Scene(s) = &case.volume.source else {
                unreachable!()
            };
            assert_eq!(volume.sample_type(), s.sample_type);
            assert_eq!(volume.layout(), s.layout);
            let frame = case.prepare(volume).unwrap().frame().unwrap();
            assert!(frame.stats.counters.samples > 0);
            samples.insert((s.sample_type, frame.stats.counters.samples));
        }
        // RAM/mapped and linear/bricked never change the samples (per sample type).
        assert_eq!(samples.len(), 2, "{samples:?}");
        // 2 sample types × 2 layouts, each generated once.
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 4);
        let spec = VolumeSpec::shapes(48);
        let path = spec.prepare(dir.path()).unwrap();
        let before = std::fs::metadata(&path).unwrap().modified().unwrap();
        spec.prepare(dir.path()).unwrap();
        assert_eq!(
            std::fs::metadata(&path).unwrap().modified().unwrap(),
            before
        );
    }

    #[test]
    fn sequential_and_parallel_cases_take_the_same_samples() {
        let dir = tempfile::tempdir().unwrap();
        let mut volumes = Volumes::new(dir.path());
        let cases: Vec<BenchCase> = parallel_cases(true)
            .into_iter()
            .filter(|c| c.brick == Some(16))
            .collect();
        let volume = volumes.get(&cases[0].volume).unwrap();
        let counts: HashSet<u64> = cases
            .iter()
            .map(|c| c.prepare(volume).unwrap().samples().unwrap())
            .collect();
        assert_eq!(counts.len(), 1);
    }

    #[test]
    fn a_missing_file_is_an_error_naming_it() {
        let spec = VolumeSpec::file("/nonexistent/x.vol", Access::Mapped);
        assert_eq!(spec.name(), "x-mapped");
        let err = spec.open(Path::new("/tmp")).unwrap_err();
        assert!(format!("{err:#}").contains("/nonexistent/x.vol"), "{err:#}");
    }
}
