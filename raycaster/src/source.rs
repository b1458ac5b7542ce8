//! The front ends' façade: where a volume comes from (a built-in generated scene
//! or a file) and the defaults that go with it — the opened volume and its
//! labels, a fitting transfer-function preset and value domain, and the camera
//! framing of its box. The `raycaster` command and the viewer both open volumes
//! through [`open`], so they agree on every default.

use std::path::{Path, PathBuf};

use glam::Vec3;

use crate::import::{DEFAULT_IN_MEMORY_LIMIT, ImportError};
use crate::render::{Orbit, TransferError, TransferFunction, patient_axes};
use crate::synth::{SceneKind, synthesize, synthesize_labels};
use crate::volume::{
    Access, Content, OpenOptions, SampleType, Volume, VolumeError, VolumeErrorKind,
};

/// Where a volume comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum VolumeSource {
    /// A generated scene of `size³` u8 voxels, in RAM.
    BuiltIn {
        /// Which scene.
        kind: SceneKind,
        /// Voxels per axis.
        size: u32,
        /// Seed of the scene's random placement.
        seed: u64,
    },
    /// A `.vol` file (mapped or read into RAM) or a scan in a foreign format
    /// (NRRD, NIfTI-1, MetaImage, a DICOM series folder), converted in RAM up to
    /// [`DEFAULT_IN_MEMORY_LIMIT`] bytes.
    File {
        /// The file (or DICOM folder).
        path: PathBuf,
        /// How a `.vol` file is accessed.
        access: Access,
    },
}

/// Why a source cannot be opened.
#[derive(Debug, thiserror::Error)]
pub enum SourceError {
    /// No path was given.
    #[error("no file given: the path of a volume (.vol, .nrrd, .nii, .mhd, DICOM folder)")]
    NoPath,
    /// The file cannot be opened or imported.
    #[error("cannot open: {source}")]
    Import {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        source: ImportError,
    },
    /// The file is a `.vol` that cannot be opened.
    #[error("cannot open: {source}")]
    Volume {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        source: VolumeError,
    },
    /// The file holds object ids, not data.
    #[error("{0} is a label volume (object ids), not data: open the data volume and a label scene")]
    LabelsNotData(PathBuf),
    /// Generating a built-in scene failed.
    #[error("built-in scene: {0}")]
    BuiltIn(VolumeError),
}

/// A volume opened from a [`VolumeSource`], with its defaults.
#[derive(Debug)]
pub struct OpenedVolume {
    /// The data.
    pub volume: Volume,
    /// Its segmentation, when it comes with one (built-in scenes with labels).
    pub labels: Option<Volume>,
    /// A name for people (the path, or the built-in scene and its size).
    pub name: String,
    /// The transfer-function preset that suits it ([`crate::windows::fit`]).
    pub preset: &'static str,
    /// The stored-value domain that suits it; see [`Self::default_domain`].
    pub domain: Option<[f32; 2]>,
    /// What opening it should tell its user beside its name: a scan's values
    /// that were NaN or infinite ([`crate::convert::non_finite_warning`]).
    pub warning: Option<String>,
}

/// The preset that suits a built-in scene.
pub fn scene_preset(kind: SceneKind) -> &'static str {
    match kind {
        SceneKind::Shapes => "shapes",
        SceneKind::Shells => "shells",
        SceneKind::Noise => "cloud",
        SceneKind::Gradient => "rainbow",
    }
}

/// Opens `source`.
pub fn open(source: &VolumeSource) -> Result<OpenedVolume, SourceError> {
    match source {
        VolumeSource::BuiltIn { kind, size, seed } => {
            let n = *size;
            let scene = kind.build([n; 3], *seed);
            let name = format!("built-in {} scene {n}³", kind.name());
            let volume = synthesize(scene.as_ref(), &name, [n; 3], [1.0; 3], SampleType::U8)
                .map_err(SourceError::BuiltIn)?;
            let labels = synthesize_labels(scene.as_ref(), &name, [n; 3], [1.0; 3])
                .map_err(SourceError::BuiltIn)?;
            Ok(OpenedVolume {
                volume,
                labels,
                name,
                preset: scene_preset(*kind),
                domain: None,
                warning: None,
            })
        }
        VolumeSource::File { path, access } => {
            let (volume, warning) = open_file(path, *access)?;
            let fit = crate::windows::fit(&volume);
            Ok(OpenedVolume {
                volume,
                labels: None,
                name: path.display().to_string(),
                preset: fit.preset,
                domain: fit.domain,
                warning,
            })
        }
    }
}

/// The volume at `path`, and the warning its import gave, if any.
fn open_file(path: &Path, access: Access) -> Result<(Volume, Option<String>), SourceError> {
    if path.as_os_str().is_empty() {
        return Err(SourceError::NoPath);
    }
    let (volume, warning) = if crate::import::detect(path).is_some() {
        let import_error = |source| SourceError::Import {
            path: path.to_path_buf(),
            source,
        };
        crate::import::open(path)
            .map_err(import_error)?
            .to_volume_noting(DEFAULT_IN_MEMORY_LIMIT, &crate::job::Job::silent())
            .map_err(import_error)?
    } else {
        let options = OpenOptions {
            access,
            ..OpenOptions::default()
        };
        let volume = Volume::open_with(path, options).map_err(|source| SourceError::Volume {
            path: path.to_path_buf(),
            source,
        })?;
        (volume, None)
    };
    if volume.content() == Content::Labels {
        return Err(SourceError::LabelsNotData(path.to_path_buf()));
    }
    Ok((volume, warning))
}

/// Opens the label volume at `path` (a `.vol` of object ids), saying what to
/// do with a foreign segmentation or a volume of values.
pub fn open_labels(path: &Path) -> Result<Volume, VolumeError> {
    let refuse = |kind| Err(VolumeError::new(path, kind));
    if crate::import::detect(path).is_some() {
        return refuse(VolumeErrorKind::ForeignLabels {
            file: path.display().to_string(),
        });
    }
    let labels = Volume::open(path)?;
    if labels.content() != Content::Labels {
        return refuse(VolumeErrorKind::ValuesNotLabels);
    }
    Ok(labels)
}

impl OpenedVolume {
    /// The stored-value domain a transfer function without its own maps to 0..1
    /// ([`crate::windows::fit`]): −1000..2000 HU for CT, the 0.5th..99.5th
    /// percentile of other u16 data, `None` (the type's range) for u8.
    pub fn default_domain(&self) -> Option<[f32; 2]> {
        self.domain
    }

    /// The suiting preset over the default domain.
    pub fn default_transfer(&self) -> TransferFunction {
        let mut tf = TransferFunction::preset(self.preset).expect("built-in preset");
        tf.domain = self.default_domain();
        tf
    }

    /// `name` (a preset or a transfer-function file) with the default domain
    /// when it has none of its own.
    pub fn transfer(&self, name: &str) -> Result<TransferFunction, TransferError> {
        let path = Path::new(name);
        let mut tf = if path.is_file() {
            TransferFunction::load(path)?
        } else {
            TransferFunction::preset(name)?
        };
        if tf.domain.is_none() {
            tf.domain = self.default_domain();
        }
        Ok(tf)
    }

    /// The world box of level 0 (every level is framed alike).
    pub fn world_box(&self) -> (Vec3, Vec3) {
        world_box(&self.volume)
    }

    /// The default view framing the volume's box (with its margin), in the
    /// patient's directions when the file gives them.
    pub fn default_view(&self) -> Orbit {
        let (lo, hi) = self.world_box();
        Orbit::default_view(lo, hi).with_axes(patient_axes(self.volume.orientation()))
    }
}

/// The world box of `volume`'s voxel centres, from the origin; an axis of one
/// voxel gets the extent of two, so that the box never collapses.
pub fn world_box(volume: &Volume) -> (Vec3, Vec3) {
    let dims = volume.dims();
    let spacing = volume.spacing();
    let hi = Vec3::from([0, 1, 2].map(|a| (dims[a].max(2) - 1) as f32 * spacing[a]));
    (Vec3::ZERO, hi)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_built_in_scene_opens_with_its_labels_preset_and_box() {
        let opened = open(&VolumeSource::BuiltIn {
            kind: SceneKind::Shells,
            size: 24,
            seed: 1,
        })
        .unwrap();
        assert_eq!(opened.volume.dims(), [24; 3]);
        assert!(opened.labels.is_some(), "shells bring their labels");
        assert_eq!(opened.preset, "shells");
        assert_eq!(opened.default_domain(), None, "u8: the type's range");
        assert_eq!(opened.world_box(), (Vec3::ZERO, Vec3::splat(23.0)));
        assert!(opened.name.contains("shells"));
    }

    #[test]
    fn files_that_are_missing_labels_or_empty_paths_are_refused_by_name() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("missing.vol");
        let e = open(&VolumeSource::File {
            path: missing,
            access: Access::Mapped,
        })
        .unwrap_err();
        assert!(e.to_string().contains("missing.vol"), "{e}");
        let e = open(&VolumeSource::File {
            path: PathBuf::new(),
            access: Access::Mapped,
        })
        .unwrap_err();
        assert!(matches!(e, SourceError::NoPath), "{e}");
    }
}
