//! Opening volumes for the viewer: files or the built-in generated scene, with
//! what the panels need (value domain, histogram, a fitting preset).

use std::path::Path;
use std::sync::Arc;

use anyhow::Result;
use raycaster::source::{self, OpenedVolume, VolumeSource};
use raycaster::synth::SceneKind;
use raycaster::volume::{Access, SampleType, Volume};

/// Bins of the histogram drawn behind the transfer function.
pub const HISTOGRAM_BINS: usize = 256;
/// Voxels the histogram looks at, at most (a regular subsample of big volumes).
const HISTOGRAM_SAMPLES: u64 = 2_000_000;
/// Volumes up to this many bytes of samples are subsampled for the histogram.
const SMALL_VOLUME_BYTES: u64 = 256 << 20;
/// Foreign scans up to this many bytes of samples are converted in RAM.
pub const IN_MEMORY_LIMIT: u64 = raycaster::import::DEFAULT_IN_MEMORY_LIMIT;
/// Edge of the built-in scene: `raycaster render`'s.
pub const BUILT_IN_SIZE: u32 = raycaster::synth::DEFAULT_SCENE_SIZE;

/// A volume ready to hand to the render front.
#[derive(Clone)]
pub struct LoadedVolume {
    /// The data.
    pub volume: Arc<Volume>,
    /// Its segmentation, when it comes with one (built-in scenes).
    pub labels: Option<Arc<Volume>>,
    /// One line for the status bar.
    pub description: String,
    /// Raw value domain the transfer function maps to 0..1 (u16: the data range).
    pub domain: Option<[f32; 2]>,
    /// Counts per bin over the domain.
    pub histogram: Vec<u64>,
    /// The preset that suits it.
    pub preset: &'static str,
    /// What opening it should tell its user (a scan's NaN or infinite values).
    pub warning: Option<String>,
}

impl LoadedVolume {
    /// The message line's words once it opened: `opened` and `what` (its
    /// description, or the session it came from), with its warning if any.
    pub fn opened_message(&self, what: &str) -> String {
        match &self.warning {
            Some(warning) => format!("opened {what}; warning: {warning}"),
            None => format!("opened {what}"),
        }
    }
}

/// The built-in scene `kind` of `size³` voxels (seed 1), as the viewer starts with.
pub fn built_in(kind: SceneKind, size: u32) -> Result<LoadedVolume> {
    open_source(&VolumeSource::BuiltIn {
        kind,
        size,
        seed: 1,
    })
}

/// Opens a built-in scene or a file (see [`open_file`]).
pub fn open_source(source: &VolumeSource) -> Result<LoadedVolume> {
    Ok(finish(source::open(source)?))
}

/// Opens a `.vol` file (mapped, never read whole) or a scan in a foreign format
/// (NRRD, NIfTI-1, MetaImage, a DICOM series folder), converted in RAM when it
/// takes at most [`IN_MEMORY_LIMIT`]; bigger scans are refused with the
/// `volgen convert` command that makes them a `.vol` file. The policy (what opens
/// how, which preset suits it) is the library's [`raycaster::source`], shared with
/// the `raycaster` command.
pub fn open_file(path: &Path) -> Result<LoadedVolume> {
    open_source(&file_source(path)).map_err(|e| {
        // A session or scene typed where a volume belongs: say what opens it.
        if raycaster::files::is_toml_name(path) && path.is_file() {
            anyhow::anyhow!(
                "{}: is a TOML file, not a volume: Open session opens a saved session, and a two-level scene loads in the Segments panel",
                path.display()
            )
        } else {
            e
        }
    })
}

/// The source of a file the viewer opens (mapped).
pub fn file_source(path: &Path) -> VolumeSource {
    VolumeSource::File {
        path: path.to_path_buf(),
        access: Access::Mapped,
    }
}

fn finish(opened: OpenedVolume) -> LoadedVolume {
    let domain = opened.default_domain();
    let OpenedVolume {
        volume,
        labels,
        name,
        preset,
        warning,
        ..
    } = opened;
    let labels = labels.map(Arc::new);
    let [x, y, z] = volume.dims();
    let histogram = histogram(&volume, domain);
    let description = format!(
        "{name}: {x}×{y}×{z} {}, {}",
        match volume.sample_type() {
            SampleType::U8 => "u8",
            SampleType::U16 => "u16",
        },
        volume.layout()
    );
    LoadedVolume {
        volume: Arc::new(volume),
        labels,
        description,
        domain,
        histogram,
        preset,
        warning,
    }
}

/// Counts binned over `domain` (default: the sample type's range), without a pass
/// over a large file: every voxel of the coarsest pyramid level when the file has
/// a pyramid; a regular subsample of small volumes; for large volumes without a
/// pyramid, an estimate from the stored brick value ranges (each brick's voxels
/// spread evenly over its range), which reads nothing.
pub fn histogram(volume: &Volume, domain: Option<[f32; 2]>) -> Vec<u64> {
    let coarsest = volume.level(volume.level_count() - 1);
    let small = coarsest.data_bytes() <= SMALL_VOLUME_BYTES;
    if !small {
        return histogram_from_ranges(volume, domain);
    }
    let volume = coarsest;
    let dims = volume.dims();
    let total: u64 = dims.iter().map(|&d| u64::from(d)).product();
    let stride = ((total as f64 / HISTOGRAM_SAMPLES as f64).cbrt().ceil() as u32).max(1);
    let [lo, hi] = domain.unwrap_or([0.0, f32::from(volume.sample_type().max_value())]);
    let width = (hi - lo).max(1.0);
    let mut counts = vec![0u64; HISTOGRAM_BINS];
    for z in (0..dims[2]).step_by(stride as usize) {
        for y in (0..dims[1]).step_by(stride as usize) {
            for x in (0..dims[0]).step_by(stride as usize) {
                let v = f32::from(volume.voxel([x, y, z]));
                let bin = ((v - lo) / width * HISTOGRAM_BINS as f32).floor();
                if (0.0..HISTOGRAM_BINS as f32).contains(&bin) {
                    counts[bin as usize] += 1;
                } else if v == hi {
                    counts[HISTOGRAM_BINS - 1] += 1;
                }
            }
        }
    }
    counts
}

/// The histogram estimated from the brick value ranges alone.
fn histogram_from_ranges(volume: &Volume, domain: Option<[f32; 2]>) -> Vec<u64> {
    let [lo, hi] = domain.unwrap_or([0.0, f32::from(volume.sample_type().max_value())]);
    let width = (hi - lo).max(1.0);
    let bin = |v: f32| ((v - lo) / width * HISTOGRAM_BINS as f32).floor();
    let ranges = volume.ranges();
    let grid = ranges.grid();
    let per_brick = u64::from(grid.step()).pow(3);
    let mut counts = vec![0u64; HISTOGRAM_BINS];
    for &[l, h] in ranges.as_slice() {
        let first = bin(f32::from(l)).clamp(0.0, HISTOGRAM_BINS as f32 - 1.0) as usize;
        let last = bin(f32::from(h)).clamp(0.0, HISTOGRAM_BINS as f32 - 1.0) as usize;
        let share = per_brick / (last - first + 1) as u64;
        for c in &mut counts[first..=last] {
            *c += share.max(1);
        }
    }
    counts
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_built_in_scene_loads_with_a_histogram() {
        let loaded = built_in(SceneKind::Shells, 32).unwrap();
        assert_eq!(loaded.volume.dims(), [32; 3]);
        assert!(loaded.labels.is_some(), "shells bring their labels");
        assert_eq!(loaded.histogram.len(), HISTOGRAM_BINS);
        assert_eq!(loaded.histogram.iter().sum::<u64>(), 32 * 32 * 32);
        assert!(loaded.description.contains("32×32×32"));
        assert_eq!(loaded.warning, None);
        assert_eq!(loaded.opened_message("x"), "opened x");
    }

    #[test]
    fn a_scan_with_nan_values_opens_and_says_how_many() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("f.nrrd");
        let mut nrrd =
            b"NRRD0004\ntype: float\ndimension: 3\nsizes: 2 2 2\nendian: little\nencoding: raw\n\n"
                .to_vec();
        nrrd.extend(
            [1.0f32, f32::NAN, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0]
                .iter()
                .flat_map(|v| v.to_le_bytes()),
        );
        std::fs::write(&path, nrrd).unwrap();
        let loaded = open_file(&path).unwrap();
        let message = loaded.opened_message(&loaded.description);
        assert!(
            message.starts_with("opened ")
                && message.contains("; warning: ")
                && message.contains("f.nrrd: 1 of its 8 values is NaN or infinite"),
            "{message}"
        );
    }

    #[test]
    fn large_files_get_their_histogram_without_a_pass_over_the_data() {
        use raycaster::io::{WriteOptions, write_volume};
        use raycaster::volume::{Content, Format, Header, Layout};
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("ramp.vol");
        let dims = [130, 40, 40];
        let header = Header::new(
            dims,
            [1.0; 3],
            Layout::Bricked { side: 16 },
            SampleType::U8,
            Content::Scalar,
            Format::Extended,
        );
        let plane = (dims[1] * dims[2]) as usize;
        let job = raycaster::job::Job::silent();
        write_volume::<u8>(
            &path,
            &header,
            &WriteOptions::default(),
            &job,
            |x0, _, slab| {
                for (i, v) in slab.iter_mut().enumerate() {
                    *v = (x0 as usize + i / plane) as u8;
                }
                Ok(())
            },
        )
        .unwrap();
        let loaded = open_file(&path).unwrap();
        // The coarsest level (33×10×10) is counted, every voxel of it.
        assert_eq!(loaded.volume.level_count(), 3);
        assert_eq!(loaded.histogram.iter().sum::<u64>(), 33 * 10 * 10);
        assert_eq!(loaded.histogram[200], 0);
        // The estimate from ranges covers the values present, and only those.
        let estimate = histogram_from_ranges(&loaded.volume, None);
        assert!(estimate[..130].iter().all(|&c| c > 0), "{estimate:?}");
        assert!(estimate[130..].iter().all(|&c| c == 0), "{estimate:?}");
    }

    #[test]
    fn bad_files_are_named_errors() {
        let dir = tempfile::tempdir().unwrap();
        let e = open_file(&dir.path().join("missing.vol")).err().unwrap();
        assert!(format!("{e:#}").contains("missing.vol"), "{e:#}");
        let junk = dir.path().join("junk.vol");
        std::fs::write(&junk, b"not a volume at all").unwrap();
        let e = open_file(&junk).err().unwrap();
        assert!(format!("{e:#}").contains("junk.vol"), "{e:#}");
        assert!(open_file(Path::new("")).is_err());
    }
}
