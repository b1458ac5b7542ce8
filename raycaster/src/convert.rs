//! Converting raw files and `.vol` files into `.vol` files of another layout, brick
//! size or sample type, streaming in bounded memory.

use std::path::Path;

use crate::io::{Input, WriteOptions, WriteSummary, write_volume};
use crate::job::Job;
use crate::volume::{
    Content, Format, Header, Layout, Sample, SampleType, VolumeError, VolumeErrorKind,
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
    /// `None` copies values when the output type holds them all and otherwise uses
    /// the input's own min..max (found in an extra streaming pass).
    pub window: Option<(f32, f32)>,
}

/// What a conversion did.
#[derive(Clone, Debug)]
pub struct ConvertSummary {
    /// The window applied, if values were mapped rather than copied.
    pub window: Option<(f32, f32)>,
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
    if same_file(input.path(), output) {
        return Err(VolumeError::new(output, VolumeErrorKind::SameFile));
    }
    let content = input.content();
    let value_type = input.value_type();
    let sample_type = options.sample_type.unwrap_or(match value_type {
        crate::io::InputType::U8 => SampleType::U8,
        _ => SampleType::U16,
    });
    let spec_error = |msg: &str| VolumeError::new(output, VolumeErrorKind::RawSpec(msg.into()));
    if content == Content::Labels && (sample_type != SampleType::U8 || options.window.is_some()) {
        return Err(spec_error(
            "a label volume stays u8 ids: no other sample type, no window",
        ));
    }
    if sample_type == SampleType::U16 && options.format == Format::Thesis {
        return Err(spec_error(
            "the thesis format holds u8 samples only; use the extended format for u16",
        ));
    }
    let spacing = options
        .spacing
        .or(input.header().map(|h| h.spacing))
        .unwrap_or([1.0; 3]);
    let header = Header::new(
        input.dims(),
        spacing,
        options.layout,
        sample_type,
        content,
        options.format,
    );
    let window = match options.window {
        Some(w) => Some(w),
        None if value_type.fits_in(sample_type) => None,
        None => Some(input.value_range(job)?.unwrap_or((0.0, 0.0))),
    };
    let written = match sample_type {
        SampleType::U8 => copy_slabs::<u8>(input, output, &header, window, write, job)?,
        SampleType::U16 => copy_slabs::<u16>(input, output, &header, window, write, job)?,
    };
    Ok(ConvertSummary {
        window,
        header,
        written,
    })
}

fn copy_slabs<T: Sample>(
    input: &Input,
    output: &Path,
    header: &Header,
    window: Option<(f32, f32)>,
    write: &WriteOptions,
    job: &Job,
) -> Result<WriteSummary, VolumeError> {
    let map = |v: f32| match window {
        // `as` saturates: values beyond the type clamp, NaN becomes 0.
        None => T::from_u16_saturating(v as u16),
        Some((lo, hi)) if hi > lo => T::from_unit((v - lo) / (hi - lo)),
        Some(_) => T::from_unit(0.0),
    };
    write_volume::<T>(output, header, write, job, |x0, x1, slab| {
        input.read_slab(x0, x1, &map, slab)
    })
}

/// Whether two paths name the same existing file.
fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}
