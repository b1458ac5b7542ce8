//! Value windows: the CT window/level presets people name (in Hounsfield
//! units), and the transfer-function preset and domain that fit a volume's data
//! when nothing is given, shared by the `raycaster` command and the viewer.

use crate::volume::{SampleType, Volume};

/// A named window in Hounsfield units: values `level ± width / 2` span the
/// transfer function (or black to white in a slice).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NamedWindow {
    /// The name given on the command line (`--domain lung`).
    pub name: &'static str,
    /// The window's centre, HU.
    pub level: f32,
    /// The window's width, HU.
    pub width: f32,
    /// What it shows.
    pub about: &'static str,
}

impl NamedWindow {
    /// `[level − width/2, level + width/2]`, HU.
    pub fn range(&self) -> [f32; 2] {
        [self.level - self.width / 2.0, self.level + self.width / 2.0]
    }
}

/// The CT window a CT scan opens with: −1000..2000 HU, air to dense bone.
pub const CT_DEFAULT_WINDOW: NamedWindow = NamedWindow {
    name: "ct",
    level: 500.0,
    width: 3000.0,
    about: "air to dense bone (−1000..2000 HU); what CT scans open with",
};

/// The named windows, the usual radiology settings.
pub const NAMED_WINDOWS: [NamedWindow; 5] = [
    CT_DEFAULT_WINDOW,
    NamedWindow {
        name: "bone",
        level: 400.0,
        width: 1800.0,
        about: "bone (−500..1300 HU)",
    },
    NamedWindow {
        name: "soft-tissue",
        level: 40.0,
        width: 400.0,
        about: "soft tissue of chest and abdomen (−160..240 HU)",
    },
    NamedWindow {
        name: "lung",
        level: -600.0,
        width: 1500.0,
        about: "lung parenchyma (−1350..150 HU)",
    },
    NamedWindow {
        name: "brain",
        level: 40.0,
        width: 80.0,
        about: "brain (0..80 HU)",
    },
];

/// The named window called `name`.
pub fn named_window(name: &str) -> Option<&'static NamedWindow> {
    NAMED_WINDOWS.iter().find(|w| w.name == name)
}

/// The names of [`NAMED_WINDOWS`], comma-separated (for messages and help).
pub fn named_window_list() -> String {
    NAMED_WINDOWS.map(|w| w.name).join(", ")
}

/// What kind of data a volume holds, as far as its defaults go.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DataKind {
    /// 8-bit data (generated scenes, the thesis's files): the type's range.
    Bytes,
    /// A CT scan: values in Hounsfield units (said by the file, or i16 values
    /// reaching down to air).
    Ct,
    /// Other data (16-bit MR, microscopy, simulations; 8-bit scans placed in
    /// the patient).
    Generic,
}

/// The defaults that fit a volume's data.
#[derive(Clone, Debug, PartialEq)]
pub struct DataFit {
    /// What the data looks like.
    pub kind: DataKind,
    /// The transfer-function preset to start with.
    pub preset: &'static str,
    /// The stored-value domain the preset spans (`None`: the sample type's range).
    pub domain: Option<[f32; 2]>,
}

/// Below this percentile and above its mirror, values are left out of a generic
/// volume's default domain (outliers and hot spots).
const TAIL_PERCENT: f64 = 0.5;
/// Voxels read at most to find a generic volume's percentiles.
const PERCENTILE_SAMPLES: u64 = 1 << 18;

/// The preset and domain a first render of `volume` uses without flags:
/// - u8 data: the `shapes` preset over the type's range (generated scenes, the
///   thesis's files), but for a scan placed in the patient (an orientation:
///   an MR or CT converted to u8) the generic `ct-skin` below (the `shapes`
///   colours painted a head blue and orange);
/// - CT (the file says Hounsfield units, or the values came from i16 and reach
///   down to air, ≤ −900): `ct-bone` over −1000..2000 HU;
/// - other u16 data: `ct-skin` over the 0.5th to 99.5th percentile of the
///   values, counted on a strided sample of at most 2^18 voxels of level 0
///   where it has at most 2^24 voxels, else on the coarsest pyramid level; a
///   large volume without a pyramid gets its stored value range (no pass over
///   the data).
pub fn fit(volume: &Volume) -> DataFit {
    if volume.sample_type() == SampleType::U8 && volume.orientation().is_none() {
        return DataFit {
            kind: DataKind::Bytes,
            preset: "shapes",
            domain: None,
        };
    }
    let units = volume.value_units();
    let [lo, hi] = volume.ranges().overall();
    if looks_like_ct(volume) {
        return DataFit {
            kind: DataKind::Ct,
            preset: "ct-bone",
            domain: Some(units.stored_range(CT_DEFAULT_WINDOW.range())),
        };
    }
    let range = (hi > lo).then(|| [f32::from(lo), f32::from(hi)]);
    DataFit {
        kind: DataKind::Generic,
        preset: "ct-skin",
        domain: percentile_domain(volume).or(range),
    }
}

/// Whether `volume` holds CT values: its units say HU, or it was stored from
/// i16 values (offset −32768, no unit known) whose smallest value is air.
pub fn looks_like_ct(volume: &Volume) -> bool {
    let units = volume.value_units();
    if units.is_hounsfield() {
        return true;
    }
    let from_i16 = units.unit.is_empty() && units.scale == 1.0 && units.offset == -32768.0;
    let [lo, hi] = volume.ranges().overall();
    from_i16 && units.value(f64::from(lo)) <= -900.0 && units.value(f64::from(hi)) >= 0.0
}

/// Whether a named CT window (in Hounsfield units) would window `volume`'s
/// numbers as something they are not: values that do not look like CT
/// ([`looks_like_ct`]), stored samples without units or values in units of
/// their own. Front ends warn of it; the
/// window then applies to the stored values as they are.
pub fn ct_window_misreads(volume: &Volume) -> bool {
    !looks_like_ct(volume)
}

/// What a CT window's warning says of `volume`, whose values a CT window
/// misreads ([`ct_window_misreads`]): stored samples without units, or values
/// in units of their own (an MR series' DICOM values) that are not
/// Hounsfield units.
pub fn not_ct_values(volume: &Volume) -> &'static str {
    if volume.value_units().is_identity() {
        "holds stored samples without value units"
    } else {
        "does not look like a CT scan (its values are not said to be Hounsfield units and do not reach down to air)"
    }
}

/// The 0.5th..99.5th percentile of stored values, from a strided sample of
/// level 0 where that is small, else from the coarsest pyramid level; `None`
/// when neither is cheap or the values are flat.
///
/// Level 0 first: a scan opened directly (read into memory, no pyramid) and
/// the same scan converted (with a pyramid, whose averaged coarse levels have
/// narrower tails) then get one domain, and so one first picture.
fn percentile_domain(volume: &Volume) -> Option<[f32; 2]> {
    let voxels_of = |v: &Volume| v.dims().iter().map(|&d| u64::from(d)).product::<u64>();
    let source = match volume.level_count() {
        n if n > 1 && voxels_of(volume) > 64 * PERCENTILE_SAMPLES => volume.level(n - 1),
        _ => volume,
    };
    let [x, y, z] = source.dims();
    let voxels = u64::from(x) * u64::from(y) * u64::from(z);
    // A mapped volume read at a stride faults in a page per sample: only small
    // volumes (a few pages per sample at most) are sampled at level 0.
    if voxels > 64 * PERCENTILE_SAMPLES && std::ptr::eq(source, volume) {
        return None;
    }
    let stride = (voxels / PERCENTILE_SAMPLES).max(1);
    let mut values = Vec::with_capacity((voxels / stride) as usize + 1);
    let mut i = 0;
    while i < voxels {
        let (vx, rest) = (
            i / (u64::from(y) * u64::from(z)),
            i % (u64::from(y) * u64::from(z)),
        );
        let (vy, vz) = (rest / u64::from(z), rest % u64::from(z));
        values.push(source.voxel([vx as u32, vy as u32, vz as u32]));
        i += stride;
    }
    values.sort_unstable();
    let at = |percent: f64| {
        let k = ((values.len() - 1) as f64 * percent / 100.0).round() as usize;
        f32::from(values[k])
    };
    let (lo, hi) = (at(TAIL_PERCENT), at(100.0 - TAIL_PERCENT));
    (hi > lo).then_some([lo, hi])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::volume::{Content, Format, Header, Layout, ValueUnits};

    fn u16_volume(values: impl Fn(u32) -> u16, units: Option<ValueUnits>) -> Volume {
        let dims = [16, 16, 16];
        let header = Header::new(
            dims,
            [1.0; 3],
            Layout::Linear,
            SampleType::U16,
            Content::Scalar,
            Format::Extended,
        )
        .with_units(units);
        let samples: Vec<u16> = (0..16 * 16 * 16).map(values).collect();
        Volume::from_samples("test.vol", &header, &samples).unwrap()
    }

    #[test]
    fn named_windows_are_level_plus_minus_half_the_width() {
        assert_eq!(named_window("lung").unwrap().range(), [-1350.0, 150.0]);
        assert_eq!(named_window("ct").unwrap().range(), [-1000.0, 2000.0]);
        assert!(named_window("lungs").is_none());
        assert!(named_window_list().contains("soft-tissue"));
    }

    #[test]
    fn ct_opens_with_the_ct_window_and_other_data_with_percentiles() {
        // i16 CT stored as HU + 32768, from −1024 (air) to 1500 HU, no unit said.
        let from_i16 = ValueUnits::new(1.0, -32768.0, "").unwrap();
        let ct = u16_volume(
            |i| (32768 - 1024 + (i % 2525)) as u16,
            Some(from_i16.clone()),
        );
        let f = fit(&ct);
        assert_eq!((f.kind, f.preset), (DataKind::Ct, "ct-bone"));
        assert_eq!(f.domain, Some([31768.0, 34768.0]));
        // The same i16 origin without air (an MR scan in i16) is generic.
        let mr = u16_volume(|i| (32768 + (i % 1000)) as u16, Some(from_i16));
        assert_eq!(fit(&mr).kind, DataKind::Generic);
        // A CT window on it is warned of (values in units of their own that
        // are not HU: an MR series read from DICOM); not on the CT.
        assert!(ct_window_misreads(&mr) && !ct_window_misreads(&ct));
        assert!(not_ct_values(&mr).contains("does not look like a CT scan"));
        assert!(not_ct_values(&u16_volume(|i| i as u16, None)).contains("without value units"));
        // Generic: 0.5th..99.5th percentiles; a single hot spot is left out.
        let generic = u16_volume(|i| if i == 7 { 60000 } else { (i % 1000) as u16 }, None);
        let f = fit(&generic);
        assert_eq!(f.kind, DataKind::Generic);
        let [lo, hi] = f.domain.unwrap();
        assert!(lo <= 10.0 && (985.0..=999.0).contains(&hi), "{lo}..{hi}");
        // A file that says HU is CT whatever its values.
        let said = ValueUnits::new(1.0, -1024.0, "HU").unwrap();
        assert_eq!(
            fit(&u16_volume(|i| (i % 3000) as u16, Some(said))).kind,
            DataKind::Ct
        );
    }

    /// 8-bit data opens with the `shapes` colours (generated scenes), but an
    /// 8-bit scan placed in the patient as generic data (it was painted blue
    /// and orange too).
    #[test]
    fn bytes_placed_in_the_patient_open_as_a_scan() {
        let header = |orientation| {
            Header::new(
                [16; 3],
                [1.0; 3],
                Layout::Linear,
                SampleType::U8,
                Content::Scalar,
                Format::Extended,
            )
            .with_orientation(orientation)
        };
        let samples: Vec<u8> = (0..16 * 16 * 16).map(|i| (i % 200) as u8).collect();
        let plain = Volume::from_samples("scene.vol", &header(None), &samples).unwrap();
        let f = fit(&plain);
        assert_eq!(
            (f.kind, f.preset, f.domain),
            (DataKind::Bytes, "shapes", None)
        );
        let lps = crate::volume::Orientation::from_steps(
            crate::volume::PatientSpace::Lps,
            [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            [0.0; 3],
        )
        .unwrap()
        .0;
        let scan = Volume::from_samples("mr.vol", &header(Some(lps)), &samples).unwrap();
        let f = fit(&scan);
        assert_eq!((f.kind, f.preset), (DataKind::Generic, "ct-skin"));
        let [lo, hi] = f.domain.unwrap();
        assert!(lo <= 1.0 && (195.0..=199.0).contains(&hi), "{lo}..{hi}");
    }
}
