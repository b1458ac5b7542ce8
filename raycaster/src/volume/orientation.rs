//! Where a volume lies in the patient: the direction of each voxel axis and the
//! position of the first voxel, in DICOM's patient coordinates (LPS: +x towards the
//! patient's left, +y posterior, +z superior; millimetres). Imported from NIfTI
//! (sform/qform), NRRD (`space`, `space directions`, `space origin`), MetaImage
//! (`TransformMatrix`, `Offset`) and DICOM (Image Orientation/Position), kept in the
//! extended header's orientation block (extension version 4, `docs/format.md`).

use glam::{DMat3, DVec3, Vec3};

use super::header::HeaderError;

/// Length of the orientation block that follows the value block.
pub const ORIENTATION_BLOCK_LEN: u64 = 128;
/// Magic bytes that open the orientation block.
const ORIENTATION_MAGIC: [u8; 4] = *b"RCVO";
/// How far from unit length an axis direction may be after normalising (rounding).
const UNIT_TOLERANCE: f64 = 1e-6;

/// A patient coordinate system a file may give positions in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PatientSpace {
    /// +x left, +y posterior, +z superior (DICOM, ITK, MetaImage).
    Lps,
    /// +x right, +y anterior, +z superior (NIfTI, many NRRD files).
    Ras,
    /// +x left, +y anterior, +z superior (some NRRD files).
    Las,
}

impl PatientSpace {
    /// The sign that turns each coordinate of this space into LPS.
    fn to_lps(self) -> DVec3 {
        match self {
            PatientSpace::Lps => DVec3::ONE,
            PatientSpace::Ras => DVec3::new(-1.0, -1.0, 1.0),
            PatientSpace::Las => DVec3::new(1.0, -1.0, 1.0),
        }
    }

    /// The space a NRRD `space` field names (its long or short spelling); `None`
    /// for non-anatomical spaces (`scanner-xyz`, `3D-right-handed`, ...).
    pub fn from_nrrd(name: &str) -> Option<PatientSpace> {
        match name.trim().to_ascii_lowercase().as_str() {
            // (With time: the same patient axes, and one of time beside them.)
            "left-posterior-superior" | "lps" | "left-posterior-superior-time" | "lpst" => {
                Some(PatientSpace::Lps)
            }
            "right-anterior-superior" | "ras" | "right-anterior-superior-time" | "rast" => {
                Some(PatientSpace::Ras)
            }
            "left-anterior-superior" | "las" | "left-anterior-superior-time" | "last" => {
                Some(PatientSpace::Las)
            }
            _ => None,
        }
    }

    /// A point or direction given in this space, in LPS.
    pub fn to_lps_vector(self, v: [f64; 3]) -> [f64; 3] {
        (DVec3::from(v) * self.to_lps()).to_array()
    }
}

/// The orientation of a volume in the patient (LPS, millimetres): voxel `(i, j, k)`
/// lies at `origin + i·sx·axes[0] + j·sy·axes[1] + k·sz·axes[2]`, with the
/// volume's spacing `(sx, sy, sz)`.
#[derive(Clone, Debug, PartialEq)]
pub struct Orientation {
    /// The unit direction (LPS) in which each voxel axis x, y, z grows.
    pub axes: [[f64; 3]; 3],
    /// The position (LPS, mm) of the centre of voxel (0, 0, 0).
    pub origin: [f64; 3],
}

/// Letters of the patient directions +x, +y, +z of LPS and their opposites.
const TOWARDS: [[char; 2]; 3] = [['L', 'R'], ['P', 'A'], ['S', 'I']];

impl Orientation {
    /// The orientation of a voxel-to-patient map given as the patient vectors of one
    /// voxel step on each axis (their lengths are the spacing) and the position of
    /// voxel (0, 0, 0), both in `space`. Returns it with the spacing the steps
    /// imply; an error when a step is zero or not finite, or the steps are
    /// (nearly) coplanar.
    pub fn from_steps(
        space: PatientSpace,
        steps: [[f64; 3]; 3],
        origin: [f64; 3],
    ) -> Result<(Orientation, [f64; 3]), String> {
        let mut axes = [[0.0; 3]; 3];
        let mut spacing = [0.0; 3];
        for (axis, step) in steps.iter().enumerate() {
            let v = DVec3::from(space.to_lps_vector(*step));
            let len = v.length();
            if !(len.is_finite() && len > 0.0) {
                return Err(format!(
                    "the direction of axis {axis} ({step:?}) is zero or not a number"
                ));
            }
            axes[axis] = (v / len).to_array();
            spacing[axis] = len;
        }
        let origin = space.to_lps_vector(origin);
        if !origin.iter().all(|o| o.is_finite()) {
            return Err(format!("the origin {origin:?} is not finite"));
        }
        let orientation = Orientation { axes, origin };
        orientation.validate().map_err(|e| e.to_string())?;
        Ok((orientation, spacing))
    }

    /// Checks finite numbers, unit axes and a volume that is not flat.
    pub fn validate(&self) -> Result<(), HeaderError> {
        let bad = |what: String| Err(HeaderError::BadOrientation(what));
        if !self.origin.iter().all(|o| o.is_finite()) {
            return bad(format!("origin {:?} is not finite", self.origin));
        }
        for (axis, a) in self.axes.iter().enumerate() {
            let len = DVec3::from(*a).length();
            if !len.is_finite() || (len - 1.0).abs() > UNIT_TOLERANCE {
                return bad(format!(
                    "the direction of axis {axis} {a:?} is not a unit vector"
                ));
            }
        }
        // Axes at less than about 0.6° from a common plane make no volume.
        if self.matrix().determinant().abs() < 1e-2 {
            return bad("the axis directions are (nearly) coplanar".to_string());
        }
        Ok(())
    }

    /// The matrix whose columns are the axis directions.
    fn matrix(&self) -> DMat3 {
        DMat3::from_cols(
            DVec3::from(self.axes[0]),
            DVec3::from(self.axes[1]),
            DVec3::from(self.axes[2]),
        )
    }

    /// The patient position (LPS, mm) of the voxel index `index` (fractional
    /// indices allowed) of a volume with `spacing`.
    pub fn patient_position(&self, spacing: [f32; 3], index: [f64; 3]) -> [f64; 3] {
        let steps = DVec3::from(index) * Vec3::from(spacing).as_dvec3();
        (DVec3::from(self.origin) + self.matrix() * steps).to_array()
    }

    /// A patient direction (LPS) in the renderer's volume space (voxel index ×
    /// spacing), normalised.
    pub fn to_volume(&self, patient: [f64; 3]) -> Vec3 {
        (self.matrix().inverse() * DVec3::from(patient))
            .normalize_or_zero()
            .as_vec3()
    }

    /// A direction in the renderer's volume space, in patient coordinates (LPS).
    pub fn to_patient(&self, volume: Vec3) -> [f64; 3] {
        (self.matrix() * volume.as_dvec3()).to_array()
    }

    /// Whether the axes are a mirror image of LPS (determinant below 0): then the
    /// volume space is left-handed in the patient, and a picture drawn in volume
    /// space must be mirrored to show the anatomy as it is.
    pub fn is_mirrored(&self) -> bool {
        self.matrix().determinant() < 0.0
    }

    /// The patient direction letter (`L`, `R`, `P`, `A`, `S`, `I`) closest to the
    /// LPS direction `v`; `None` for a zero vector.
    pub fn letter(v: [f64; 3]) -> Option<char> {
        let (axis, along) = Orientation::nearest_axis(v)?;
        Some(TOWARDS[axis][usize::from(!along)])
    }

    /// The patient axis (LPS: 0 L, 1 P, 2 S) nearest the LPS direction `v`,
    /// and whether `v` points along it (else against it); `None` for a zero
    /// vector.
    pub fn nearest_axis(v: [f64; 3]) -> Option<(usize, bool)> {
        let (axis, value) = v
            .iter()
            .copied()
            .enumerate()
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))?;
        (value != 0.0).then_some((axis, value > 0.0))
    }

    /// The three letters naming where each voxel axis grows, e.g. `LPS` or `RAI`.
    pub fn axis_code(&self) -> String {
        self.axes
            .iter()
            .map(|a| Orientation::letter(*a).unwrap_or('?'))
            .collect()
    }

    /// One line for people: where the voxel axes grow and where voxel (0, 0, 0) lies,
    /// e.g. `RAI (x right, y anterior, z inferior), voxel 0,0,0 at 10, -20, 30 mm LPS`,
    /// with `oblique` when an axis is more than 1° off the patient axes, and
    /// `mirrored` when the axes are a mirror image of the patient's.
    pub fn describe(&self) -> String {
        let word = |c: char| match c {
            'L' => "left",
            'R' => "right",
            'P' => "posterior",
            'A' => "anterior",
            'S' => "superior",
            _ => "inferior",
        };
        let code = self.axis_code();
        let axes: Vec<String> = code
            .chars()
            .zip(["x", "y", "z"])
            .map(|(c, axis)| format!("{axis} {}", word(c)))
            .collect();
        let largest = |a: &[f64; 3]| a.iter().fold(0f64, |m, c| m.max(c.abs()));
        let oblique = self
            .axes
            .iter()
            .any(|a| largest(a) < 1f64.to_radians().cos());
        // Micrometres at most, without trailing zeros (`-777.5`, `-146`), and no
        // −0 (a RAS origin of 0 negated into LPS).
        let [x, y, z] = self.origin.map(|c| {
            let text = format!("{c:.6}");
            match text.trim_end_matches('0').trim_end_matches('.') {
                "-0" => "0".to_string(),
                short => short.to_string(),
            }
        });
        format!(
            "{code} ({}){}{}, voxel 0,0,0 at {x}, {y}, {z} mm LPS",
            axes.join(", "),
            if oblique { ", oblique" } else { "" },
            if self.is_mirrored() { ", mirrored" } else { "" },
        )
    }

    /// The orientation block's bytes (see `docs/format.md`).
    pub(crate) fn encode(&self) -> [u8; ORIENTATION_BLOCK_LEN as usize] {
        let mut out = [0u8; ORIENTATION_BLOCK_LEN as usize];
        out[0..4].copy_from_slice(&ORIENTATION_MAGIC);
        let numbers = self.axes.iter().flatten().chain(self.origin.iter());
        for (i, n) in numbers.enumerate() {
            out[8 + 8 * i..16 + 8 * i].copy_from_slice(&n.to_le_bytes());
        }
        out
    }

    /// Parses an orientation block.
    pub(crate) fn decode(block: &[u8]) -> Result<Orientation, HeaderError> {
        let bad = |what: &str| HeaderError::BadOrientation(what.to_string());
        if block.len() < ORIENTATION_BLOCK_LEN as usize {
            return Err(bad("the orientation block is cut short"));
        }
        if block[0..4] != ORIENTATION_MAGIC {
            return Err(bad("the orientation block does not start with \"RCVO\""));
        }
        let n = |i: usize| f64::from_le_bytes(block[8 + 8 * i..16 + 8 * i].try_into().unwrap());
        let orientation = Orientation {
            axes: [[n(0), n(1), n(2)], [n(3), n(4), n(5)], [n(6), n(7), n(8)]],
            origin: [n(9), n(10), n(11)],
        };
        orientation.validate()?;
        Ok(orientation)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn oblique() -> Orientation {
        let (o, spacing) = Orientation::from_steps(
            PatientSpace::Ras,
            [[0.0, -0.5, 0.0], [2.0, 0.0, 0.0], [0.0, 0.0, -3.0]],
            [10.0, 20.0, 30.0],
        )
        .unwrap();
        assert_eq!(spacing, [0.5, 2.0, 3.0]);
        o
    }

    #[test]
    fn steps_from_ras_map_voxels_to_lps_and_back() {
        let o = oblique();
        // RAS (10, 20, 30) is LPS (−10, −20, 30).
        assert_eq!(o.origin, [-10.0, -20.0, 30.0]);
        // x grows towards RAS −y (posterior), y towards RAS +x (right).
        assert_eq!(o.axis_code(), "PRI");
        let p = o.patient_position([0.5, 2.0, 3.0], [2.0, 1.0, 1.0]);
        assert_eq!(p, [-10.0 - 2.0, -20.0 + 1.0, 30.0 - 3.0]);
        assert_eq!(o.to_volume([0.0, 1.0, 0.0]), Vec3::X);
        assert_eq!(o.to_patient(Vec3::Z), [0.0, 0.0, -1.0]);
        // P, R, I: a mirror image of L, P, S.
        assert!(o.is_mirrored());
        assert_eq!(Orientation::decode(&o.encode()).unwrap(), o);
    }

    #[test]
    fn the_origin_is_described_without_trailing_zeros() {
        let lps = |origin| Orientation {
            axes: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            origin,
        };
        assert_eq!(
            lps([-146.0, -325.0, -777.5]).describe(),
            "LPS (x left, y posterior, z superior), voxel 0,0,0 at -146, -325, -777.5 mm LPS"
        );
        assert!(
            lps([-0.0, -1e-9, -78.3063])
                .describe()
                .ends_with("at 0, 0, -78.3063 mm LPS")
        );
    }

    #[test]
    fn nonsense_is_refused() {
        let flat = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]];
        assert!(Orientation::from_steps(PatientSpace::Lps, flat, [0.0; 3]).is_err());
        let zero = [[0.0; 3], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(Orientation::from_steps(PatientSpace::Lps, zero, [0.0; 3]).is_err());
        let nan = [[f64::NAN, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
        assert!(Orientation::from_steps(PatientSpace::Lps, nan, [0.0; 3]).is_err());
        let mut block = oblique().encode();
        block[15] = 0x7f; // the first number becomes huge: not a unit axis
        assert!(Orientation::decode(&block).is_err());
        block[0] = b'X';
        assert!(Orientation::decode(&block).is_err());
        assert_eq!(PatientSpace::from_nrrd("scanner-xyz"), None);
        assert_eq!(PatientSpace::from_nrrd("RAS"), Some(PatientSpace::Ras));
    }

    #[test]
    fn letters_name_the_closest_patient_direction() {
        assert_eq!(Orientation::letter([0.9, 0.1, 0.2]), Some('L'));
        assert_eq!(Orientation::letter([0.1, -0.9, 0.2]), Some('A'));
        assert_eq!(Orientation::letter([0.1, 0.2, -0.3]), Some('I'));
        assert_eq!(Orientation::letter([0.0; 3]), None);
    }
}
