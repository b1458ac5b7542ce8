//! Converting raw files, `.vol` files and imported foreign files (NRRD, NIfTI,
//! MetaImage) into `.vol` files of another layout, brick size or sample type,
//! streaming in bounded memory.

use std::path::Path;

use crate::io::{Input, InputType, WriteOptions, WriteSummary, XRegions, write_volume};
use crate::job::Job;
use crate::volume::{
    AtPath, Content, Format, Header, Layout, Sample, SampleType, ValueUnits, VolumeError,
    VolumeErrorKind,
};

/// What the output of a conversion looks like.
#[derive(Clone, Copy, Debug)]
pub struct ConvertOptions {
    /// Output layout.
    pub layout: Layout,
    /// Output sample type; `None` keeps the input's (i16 and f32 become u16).
    pub sample_type: Option<SampleType>,
    /// Output header format.
    pub format: Format,
    /// Output spacing; `None` keeps the input's (raw inputs: 1, 1, 1).
    pub spacing: Option<[f32; 3]>,
    /// Input values mapped linearly onto the output's full range, clamped outside.
    /// `None` chooses a [`ValueMap`] with [`plan_values`].
    pub window: Option<(f32, f32)>,
    /// The input holds object ids (a segmentation): the output is a label
    /// volume (u8 ids, never interpolated), its values copied (their whole
    /// part, toward zero); values whose whole part lies beyond 0..=255, NaN
    /// or infinite ones are refused.
    pub labels: bool,
}

/// How input values become stored samples.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ValueMap {
    /// Values are stored unchanged (the output type holds them all).
    Copy,
    /// i16 values are stored as `value + 32768` in u16 samples: exact, and the same
    /// for every file, so original units are `stored − 32768`.
    Offset,
    /// Values `lo..=hi` map linearly onto the output's full range, clamped outside.
    Window(f32, f32),
}

/// The offset [`ValueMap::Offset`] adds to i16 values.
pub const I16_OFFSET: f32 = 32768.0;

impl ValueMap {
    /// What samples stored with this map mean, for input values meaning
    /// `input`: the map inverted (a window's step per stored unit) and composed
    /// with the input's units; the unit name carries over.
    pub fn output_units(self, input: &ValueUnits, sample: SampleType) -> ValueUnits {
        // value = input.scale × v + input.offset, with v = a × stored + b.
        let (a, b) = match self {
            ValueMap::Copy => (1.0, 0.0),
            ValueMap::Offset => (1.0, -f64::from(I16_OFFSET)),
            ValueMap::Window(lo, hi) if hi > lo => (
                (f64::from(hi) - f64::from(lo)) / f64::from(sample.max_value()),
                f64::from(lo),
            ),
            // A collapsed window stores one value: keep the values' origin.
            ValueMap::Window(lo, _) => (1.0, f64::from(lo)),
        };
        ValueUnits {
            scale: input.scale * a,
            offset: input.scale * b + input.offset,
            unit: input.unit.clone(),
        }
    }

    /// The function from an input value to a stored sample of type `T`.
    pub fn to_sample<T: Sample>(self) -> impl Fn(f32) -> T + Copy {
        // A window wider than `f32` holds (−2e38..2e38) is mapped in halves:
        // `hi − lo` would be infinite. (Halving is exact, and a factor of 1
        // leaves other windows' results as they were.)
        let half = match self {
            ValueMap::Window(lo, hi) if !(hi - lo).is_finite() => 0.5,
            _ => 1.0,
        };
        move |v: f32| match self {
            // `as` saturates: values beyond the type clamp, NaN becomes 0.
            ValueMap::Copy => T::from_u16_saturating(v as u16),
            ValueMap::Offset => T::from_u16_saturating((v + I16_OFFSET) as u16),
            ValueMap::Window(lo, hi) if hi > lo => {
                T::from_unit((v * half - lo * half) / (hi * half - lo * half))
            }
            ValueMap::Window(..) => T::from_unit(0.0),
        }
    }
}

/// The output sample type and value mapping for `input`: `sample_type` or the
/// default for the input (u8 stays u8, everything else becomes u16); then values are
/// copied when the output holds them all, i16 → u16 is offset by 32768, and otherwise
/// `window` (default: the input's own min..max, found in an extra streaming pass)
/// maps onto the output's full range. The third item counts the values that
/// are NaN or infinite, when that pass ran (they are stored as the window's low
/// end, and ±∞ as its ends).
pub fn plan_values(
    input: &Input,
    sample_type: Option<SampleType>,
    window: Option<(f32, f32)>,
    job: &Job,
) -> Result<(SampleType, ValueMap, Option<u64>), VolumeError> {
    let value_type = input.value_type();
    let mut non_finite = None;
    let sample_type = sample_type.unwrap_or(match value_type {
        InputType::U8 => SampleType::U8,
        _ => SampleType::U16,
    });
    let map = match window {
        // The window is given in the input's units.
        Some((lo, hi)) => {
            let [lo, hi] = input.units().stored_range([lo, hi]);
            ValueMap::Window(lo, hi)
        }
        None if value_type.fits_in(sample_type) => ValueMap::Copy,
        None if value_type == InputType::I16 && sample_type == SampleType::U16 => ValueMap::Offset,
        None => {
            let range = input.value_range(job)?;
            let Some((lo, hi)) = range.finite else {
                return Err(VolumeError::new(
                    input.path(),
                    VolumeErrorKind::NoFiniteValues,
                ));
            };
            non_finite = Some(range.non_finite);
            // (Integer types' scalings are checked against their whole
            // range when the header is read; float values only now.)
            let units = input.units();
            if let Some(value) = [lo, hi]
                .map(|v| units.value(f64::from(v)))
                .into_iter()
                .find(|v| v.is_nan() || v.abs() > f64::from(f32::MAX))
            {
                return Err(VolumeError::new(
                    input.path(),
                    VolumeErrorKind::ValuesBeyondF32 { value },
                ));
            }
            ValueMap::Window(lo, hi)
        }
    };
    Ok((sample_type, map, non_finite))
}

/// The warning for a conversion or import that stored `non_finite` of its
/// `voxels` values (NaN or infinite) as the window's ends: said once, by
/// `volgen convert`, `raycaster render` and the viewer alike.
pub fn non_finite_warning(path: &Path, non_finite: u64, voxels: u64) -> String {
    format!(
        "{}: {}: NaN is stored as the window's low end, ±infinity as its ends",
        path.display(),
        non_finite_count(non_finite, voxels)
    )
}

/// `non_finite` of `voxels` values said as a count: "3 of its 16 values are
/// NaN or infinite" (what [`non_finite_warning`] and `volgen info` say).
pub fn non_finite_count(non_finite: u64, voxels: u64) -> String {
    let verb = if non_finite == 1 { "is" } else { "are" };
    format!("{non_finite} of its {voxels} values {verb} NaN or infinite")
}

/// What a conversion did.
#[derive(Clone, Debug)]
pub struct ConvertSummary {
    /// How values were mapped to samples.
    pub values: ValueMap,
    /// Input values that were NaN or infinite, as counted by the value-range
    /// pass of a window not given (0 when it did not run).
    pub non_finite: u64,
    /// The header written.
    pub header: Header,
    /// The written file.
    pub written: WriteSummary,
}

/// Converts `input` to a `.vol` file at `output`.
pub fn convert(
    input: &Input,
    output: &Path,
    options: &ConvertOptions,
    write: &WriteOptions,
    job: &Job,
) -> Result<ConvertSummary, VolumeError> {
    if input.files().any(|f| crate::files::same_file(f, output)) {
        return Err(VolumeError::new(output, VolumeErrorKind::SameFile));
    }
    let content = if options.labels {
        Content::Labels
    } else {
        input.content()
    };
    let sample_type = options.sample_type.unwrap_or(match input.value_type() {
        _ if content == Content::Labels => SampleType::U8,
        InputType::U8 => SampleType::U8,
        _ => SampleType::U16,
    });
    let spec_error = |msg: &str| VolumeError::new(output, VolumeErrorKind::RawSpec(msg.into()));
    if content == Content::Labels && (sample_type != SampleType::U8 || options.window.is_some()) {
        return Err(spec_error(
            "a label volume stays u8 ids: no other sample type, no window",
        ));
    }
    if content == Content::Labels && options.format == Format::Thesis {
        return Err(spec_error(
            "the thesis header cannot mark a label volume (it would read as values); use the extended format",
        ));
    }
    if sample_type == SampleType::U16 && options.format == Format::Thesis {
        return Err(spec_error(
            "the thesis format holds u8 samples only; use the extended format for u16, or convert to u8 (a value window maps the values onto 0..255)",
        ));
    }
    let spacing = options.spacing.or(input.spacing()).unwrap_or([1.0; 3]);
    let header = Header::new(
        input.dims(),
        spacing,
        options.layout,
        sample_type,
        content,
        options.format,
    );
    // The header is checked before the (possibly long) value-range pass. Its
    // faults are the input's (its spacing, its units), unless a spacing was given.
    let blamed = match options.spacing {
        Some(_) => output,
        None => input.path(),
    };
    header.validate().at(blamed)?;
    let (values, non_finite) = if content == Content::Labels {
        (label_values(input, job)?, None)
    } else {
        let (_, values, non_finite) = plan_values(input, Some(sample_type), options.window, job)?;
        (values, non_finite)
    };
    // Units need the extended header; a thesis file of a windowed input keeps
    // stored values only (the summary's value map says how they were made).
    let header = match (content, options.format) {
        (Content::Scalar, Format::Extended) => {
            header.with_units(Some(values.output_units(input.units(), sample_type)))
        }
        _ => header,
    };
    // The thesis header has no room for an orientation; such files lose it.
    let header = match options.format {
        Format::Extended => header.with_orientation(input.orientation().cloned()),
        Format::Thesis => header,
    };
    header.encode().at(blamed)?;
    let written = match sample_type {
        SampleType::U8 => copy_slabs::<u8>(input, output, &header, values, write, job)?,
        SampleType::U16 => copy_slabs::<u16>(input, output, &header, values, write, job)?,
    };
    Ok(ConvertSummary {
        values,
        non_finite: non_finite.unwrap_or(0),
        header,
        written,
    })
}

/// How the values of `input` become the ids of a label volume: copied, once a
/// pass has found them all in 0..=255 (u8 inputs need none).
fn label_values(input: &Input, job: &Job) -> Result<ValueMap, VolumeError> {
    if input.value_type() == InputType::U8 {
        return Ok(ValueMap::Copy);
    }
    let refuse = |what: String| {
        Err(VolumeError::new(
            input.path(),
            VolumeErrorKind::RawSpec(format!("{what}: a label volume holds object ids 0 to 255")),
        ))
    };
    let range = input.value_range(job)?;
    match range.finite {
        _ if range.non_finite > 0 => {
            let voxels = input.dims().iter().map(|&d| u64::from(d)).product();
            refuse(non_finite_count(range.non_finite, voxels))
        }
        None => refuse("it holds no finite value".into()),
        // (Fractions are cut toward zero, at both ends: −0.5 is id 0 as
        // 255.5 is 255.)
        Some((lo, hi)) if lo <= -1.0 || hi >= 256.0 => {
            let [lo, hi] = [lo, hi].map(crate::volume::number_text);
            refuse(format!("its values span {lo} to {hi}"))
        }
        Some(_) => Ok(ValueMap::Copy),
    }
}

fn copy_slabs<T: Sample>(
    input: &Input,
    output: &Path,
    header: &Header,
    values: ValueMap,
    write: &WriteOptions,
    job: &Job,
) -> Result<WriteSummary, VolumeError> {
    let map = values.to_sample::<T>();
    // An x-fastest input is staged beside the output first: its slabs read
    // from the file itself read it whole each (quadratic in its size).
    let staged = if XRegions::needed(input) {
        let folder = crate::files::parent_dir(output);
        Some(XRegions::stage(input, folder, job)?)
    } else {
        None
    };
    write_volume::<T>(output, header, write, job, |x0, x1, slab| match &staged {
        Some(regions) => regions.read_slab(input, x0, x1, &map, slab),
        None => input.read_slab(x0, x1, &map, slab),
    })
}

/// The voxels a conversion of `input` reads before its samples' pass (an
/// x-fastest input of more than 512 MiB is staged beside the output
/// first, read once in file order): for progress totals.
pub fn staging_voxels(input: &Input) -> u64 {
    XRegions::staged_voxels(input)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn windows_wider_than_f32_holds_map_like_narrower_ones() {
        let wide = ValueMap::Window(-2e38, 2e38).to_sample::<u16>();
        let narrow = ValueMap::Window(-2.0, 2.0).to_sample::<u16>();
        for (v, n) in [
            (-2e38, -2.0),
            (-1e38, -1.0),
            (0.0, 0.0),
            (1e38, 1.0),
            (2e38, 2.0),
        ] {
            assert_eq!(wide(v), narrow(n), "{v}");
        }
        assert_eq!(wide(2e38), u16::MAX);
        assert_eq!(wide(-3e38), 0);
        let full = ValueMap::Window(f32::MIN, f32::MAX).to_sample::<u8>();
        assert_eq!([full(f32::MIN), full(0.0), full(f32::MAX)], [0, 128, 255]);
        // An ordinary window: the same results as `(v − lo) / (hi − lo)`.
        let plain = ValueMap::Window(-1000.0, 3000.0).to_sample::<u16>();
        for v in [-1000.0f32, -3.7, 0.0, 1234.5, 3000.0] {
            assert_eq!(plain(v), u16::from_unit((v - -1000.0) / 4000.0));
        }
    }
}
