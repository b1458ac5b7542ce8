//! The volumes benchmarks render: generated scenes cached as files, or given files.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use raycaster::generate::generate;
use raycaster::io::WriteOptions;
use raycaster::job::Job;
use raycaster::synth::SceneKind;
use raycaster::volume::{
    Access, Content, Format, Header, Layout, OpenOptions, Sample, SampleType, Volume, read_header,
};

/// A generated scene, stored as a `.vol` file in the benchmark cache.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SceneSpec {
    /// Which built-in scene.
    pub scene: SceneKind,
    /// Voxels per axis.
    pub dims: [u32; 3],
    /// Sample type of the file.
    pub sample_type: SampleType,
    /// Linear or bricked storage (and the stored brick side).
    pub layout: Layout,
    /// Seed of the scene (1, as `volgen generate`'s default).
    pub seed: u64,
}

impl SceneSpec {
    /// The cache file's name, e.g. `shapes-256-u8-linear.vol`,
    /// `shapes-68x256x256-u16-b16.vol`.
    pub fn file_name(&self) -> String {
        format!("{}.vol", self.name())
    }

    /// The scene's id, e.g. `shapes-256-u8-linear`.
    pub fn name(&self) -> String {
        let [x, y, z] = self.dims;
        let size = if x == y && y == z {
            x.to_string()
        } else {
            format!("{x}x{y}x{z}")
        };
        let layout = match self.layout {
            Layout::Linear => "linear".to_string(),
            Layout::Bricked { side } => format!("b{side}"),
        };
        let seed = if self.seed == 1 {
            String::new()
        } else {
            format!("-seed{}", self.seed)
        };
        format!(
            "{}-{size}-{}-{layout}{seed}",
            self.scene.name(),
            sample_type_name(self.sample_type)
        )
    }

    /// Writes the scene to `path` (atomically: a concurrent writer of the same
    /// file loses the race harmlessly).
    fn generate(&self, path: &Path) -> Result<()> {
        let header = Header::new(
            self.dims,
            [1.0; 3],
            self.layout,
            self.sample_type,
            Content::Scalar,
            Format::Extended,
        );
        let scene = self.scene.build(self.dims, self.seed);
        let options = WriteOptions {
            overwrite: true,
            ..WriteOptions::default()
        };
        generate(scene.as_ref(), &header, path, &options, &Job::silent())?;
        Ok(())
    }
}

impl SceneSpec {
    /// Whether the file at `path` holds this scene: its size, sample type,
    /// layout, spacing and content kind are the scene's, and so are the samples
    /// of nine rows spread over the volume (another scene or seed of the same
    /// size differs there; a check of every voxel would read the whole file).
    fn held_by(&self, path: &Path) -> bool {
        let header_fits = read_header(path).is_ok_and(|(h, _, _)| {
            h.dims == self.dims
                && h.sample_type == self.sample_type
                && h.layout == self.layout
                && h.spacing == [1.0; 3]
                && h.content == Content::Scalar
        });
        let options = OpenOptions {
            access: Access::Mapped,
            ..OpenOptions::default()
        };
        let Some(volume) = header_fits
            .then(|| Volume::open_with(path, options).ok())
            .flatten()
        else {
            return false;
        };
        let scene = self.scene.build(self.dims, self.seed);
        let [dx, dy, dz] = self.dims;
        let mut row = vec![0f32; dz as usize];
        [1, 2, 3].into_iter().all(|i| {
            [1, 2, 3].into_iter().all(|j| {
                let (x, y) = (dx * i / 4, dy * j / 4);
                scene.fill_row(x, y, &mut row);
                (0..dz).all(|z| {
                    let v = row[z as usize];
                    let expected = match self.sample_type {
                        SampleType::U8 => u16::from(u8::from_unit(v)),
                        SampleType::U16 => u16::from_unit(v),
                    };
                    volume.voxel([x, y, z]) == expected
                })
            })
        })
    }
}

/// `u8` or `u16`.
pub fn sample_type_name(t: SampleType) -> &'static str {
    match t {
        SampleType::U8 => "u8",
        SampleType::U16 => "u16",
    }
}

/// Where a benchmark volume comes from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum VolumeSource {
    /// A built-in scene, generated into the cache directory when missing.
    Scene(SceneSpec),
    /// An existing file (its stored type and layout are its own).
    File(PathBuf),
}

/// A benchmark volume and how it is held (mapped or read into RAM).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VolumeSpec {
    /// The file or the scene.
    pub source: VolumeSource,
    /// Mapped or in RAM.
    pub access: Access,
}

impl VolumeSpec {
    /// A u8 `shapes` scene of `n³` voxels, linear, in RAM (seed 1).
    pub fn shapes(n: u32) -> VolumeSpec {
        VolumeSpec {
            source: VolumeSource::Scene(SceneSpec {
                scene: SceneKind::Shapes,
                dims: [n; 3],
                sample_type: SampleType::U8,
                layout: Layout::Linear,
                seed: 1,
            }),
            access: Access::Ram,
        }
    }

    /// An existing file, mapped or in RAM.
    pub fn file(path: impl Into<PathBuf>, access: Access) -> VolumeSpec {
        VolumeSpec {
            source: VolumeSource::File(path.into()),
            access,
        }
    }

    /// The same volume held another way.
    pub fn with_access(mut self, access: Access) -> VolumeSpec {
        self.access = access;
        self
    }

    /// The same scene stored with another sample type (files are left alone).
    pub fn with_sample_type(mut self, sample_type: SampleType) -> VolumeSpec {
        if let VolumeSource::Scene(s) = &mut self.source {
            s.sample_type = sample_type;
        }
        self
    }

    /// The same scene stored in another layout (files are left alone).
    pub fn with_layout(mut self, layout: Layout) -> VolumeSpec {
        if let VolumeSource::Scene(s) = &mut self.source {
            s.layout = layout;
        }
        self
    }

    /// The volume's id, e.g. `shapes-256-u8-linear-ram` or `head-mapped`.
    pub fn name(&self) -> String {
        let access = match self.access {
            Access::Ram => "ram",
            Access::Mapped => "mapped",
        };
        let volume = match &self.source {
            VolumeSource::Scene(s) => s.name(),
            VolumeSource::File(p) => p.file_stem().map_or_else(
                || "volume".to_string(),
                |s| s.to_string_lossy().into_owned(),
            ),
        };
        format!("{volume}-{access}")
    }

    /// The file of the volume: a given file, or the scene's file in `cache_dir`.
    pub fn path(&self, cache_dir: &Path) -> PathBuf {
        match &self.source {
            VolumeSource::Scene(s) => cache_dir.join(s.file_name()),
            VolumeSource::File(p) => p.clone(),
        }
    }

    /// The volume's file, generated into `cache_dir` first when it is a scene
    /// whose file is missing, unreadable or not the scene's ([`SceneSpec::held_by`]:
    /// a file put there by hand was measured under the scene's name).
    pub fn prepare(&self, cache_dir: &Path) -> Result<PathBuf> {
        let path = self.path(cache_dir);
        if let VolumeSource::Scene(scene) = &self.source
            && !scene.held_by(&path)
        {
            std::fs::create_dir_all(cache_dir)
                .with_context(|| format!("cannot create {}", cache_dir.display()))?;
            eprintln!("bench: generating {} (once)", path.display());
            scene.generate(&path)?;
        }
        Ok(path)
    }

    /// Prepares the file and opens it as [`VolumeSpec::access`] says.
    pub fn open(&self, cache_dir: &Path) -> Result<Volume> {
        let path = self.prepare(cache_dir)?;
        let options = OpenOptions {
            access: self.access,
            ..OpenOptions::default()
        };
        Ok(Volume::open_with(&path, options)?)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cache file of another size, sample type or layout under a scene's
    /// name is generated again (it was measured as the scene); the scene's
    /// own file is kept.
    #[test]
    fn a_cache_file_that_is_not_the_scene_is_generated_again() {
        let dir = tempfile::tempdir().unwrap();
        let spec = VolumeSpec::shapes(12);
        let path = spec.prepare(dir.path()).unwrap();
        let dims = |p: &Path| read_header(p).unwrap().0.dims;
        assert_eq!(dims(&path), [12; 3]);
        std::fs::copy(&path, dir.path().join("kept.vol")).unwrap();
        let written = std::fs::metadata(&path).unwrap().modified().unwrap();
        spec.prepare(dir.path()).unwrap();
        assert_eq!(
            std::fs::metadata(&path).unwrap().modified().unwrap(),
            written
        );
        let of_scene = |scene: SceneKind, seed: u64| {
            let mut spec = VolumeSpec::shapes(12);
            if let VolumeSource::Scene(s) = &mut spec.source {
                (s.scene, s.seed) = (scene, seed);
            }
            spec
        };
        for other in [
            VolumeSpec::shapes(8),
            VolumeSpec::shapes(12).with_sample_type(SampleType::U16),
            VolumeSpec::shapes(12).with_layout(Layout::Bricked { side: 8 }),
            of_scene(SceneKind::Shells, 1),
            of_scene(SceneKind::Shapes, 2),
        ] {
            let stand_in = other.prepare(dir.path()).unwrap();
            std::fs::copy(&stand_in, &path).unwrap();
            spec.prepare(dir.path()).unwrap();
            let (h, _, _) = read_header(&path).unwrap();
            assert_eq!(
                (h.dims, h.sample_type, h.layout),
                ([12; 3], SampleType::U8, Layout::Linear),
                "{}",
                other.name()
            );
            assert_eq!(
                std::fs::read(&path).unwrap(),
                std::fs::read(dir.path().join("kept.vol")).unwrap(),
                "{}",
                other.name()
            );
        }
        // The scene's file with another spacing in its header.
        let mut bytes = std::fs::read(&path).unwrap();
        bytes[12..16].copy_from_slice(&2.0f32.to_le_bytes());
        std::fs::write(&path, &bytes).unwrap();
        spec.prepare(dir.path()).unwrap();
        assert_eq!(read_header(&path).unwrap().0.spacing, [1.0; 3]);
    }
}
