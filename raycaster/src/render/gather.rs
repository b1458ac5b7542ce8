//! The unshaded DVR kernel with hardware gathers (AVX2 and AVX-512, x86-64):
//! eight consecutive samples of one ray at a time, their positions, cells,
//! corner reads, trilinear values and transfer-table indices in eight SIMD
//! lanes, then the "over" steps in order.
//!
//! The shaded kernel ([`super::packet`]) shares each voxel cell's corners
//! between the samples in it through the [`super::cell_cache::CellCache`]; its
//! bookkeeping (finding the samples of one cell, entering a cell) costs more than
//! the reads it saves once no gradient is needed. Here every lane reads its own
//! eight corners with one gather per corner (`vpgatherdd`: four bytes at each
//! lane's byte offset, the voxel in their low bytes), so a chunk has no branch
//! per cell.
//!
//! Every operation is the scalar kernel's, in its order (positions as
//! [`super::pixel::SamplePositions::at`], the value as
//! [`super::sampler::trilinear`], the index as
//! [`super::transfer::TransferTable::index`], no fused multiply-adds), so the
//! frames are bit-identical to the scalar kernel's, which
//! `tests/packet_kernel.rs` checks on every level.

use super::local::Accumulation;
use super::optics::{over, partial_step};
use super::pixel::SamplePositions;
use super::sampler::BrickSampler;
use super::transfer::TransferTable;
use crate::volume::Sample;

/// Samples per chunk.
pub(crate) const GATHER_LANES: usize = 8;

/// What the gathers address in one brick: its samples as bytes and the byte
/// offsets of a cell's corners.
#[derive(Clone, Copy, Debug)]
pub(crate) struct GatherBrick<'a> {
    bytes: &'a [u8],
    /// Byte strides per axis.
    strides: [i32; 3],
    /// Byte offsets of a cell's eight corners from its lower one, in
    /// [`super::sampler::Corners`] order.
    corners: [i32; 8],
    /// Offsets above this read past the slice's end when read as four bytes.
    last_whole_read: i32,
    /// Bytes per sample (1 or 2).
    sample_size: i32,
    origin: [f32; 3],
    max_cell: [f32; 3],
}

impl<'a> GatherBrick<'a> {
    /// The gather layout of `sampler`'s brick, or `None` where a gather cannot
    /// address it (offsets beyond `i32`, a brick of under eight bytes) or this
    /// CPU lacks AVX2.
    pub(crate) fn new<T: Sample>(sampler: &BrickSampler<'a, T>) -> Option<Self> {
        if !has_avx2() {
            return None;
        }
        let (samples, strides, corner_strides) = sampler.addressing();
        let bytes: &[u8] = bytemuck::cast_slice(samples);
        let size = std::mem::size_of::<T>();
        let to_i32 = |v: usize| i32::try_from(v).ok();
        if bytes.len() < 8 || to_i32(bytes.len()).is_none() {
            return None;
        }
        let [ox, oy, oz] = corner_strides.map(|s| s * size);
        let corners = [0, oz, oy, oy + oz, ox, ox + oz, ox + oy, ox + oy + oz];
        Some(GatherBrick {
            bytes,
            strides: [
                to_i32(strides[0] * size)?,
                to_i32(strides[1] * size)?,
                to_i32(strides[2] * size)?,
            ],
            corners: corners.map(|c| c as i32),
            last_whole_read: bytes.len() as i32 - 4,
            sample_size: size as i32,
            origin: sampler.origin().to_array(),
            max_cell: sampler.max_cell_lanes().to_array(),
        })
    }
}

/// Whether this CPU has AVX2 (detected once per process by `std`).
fn has_avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// One ray's visit of a brick, marched by gathers.
pub(crate) struct GatherRay<'v, 'a, T: Sample> {
    /// The brick's layout.
    pub brick: GatherBrick<'a>,
    /// The brick, for the samples outside its cells.
    pub sampler: &'v BrickSampler<'a, T>,
    /// The frame's table.
    pub table: &'v TransferTable,
    /// The ray's sample positions.
    pub positions: SamplePositions,
    /// The ray's last sample and the fraction of a step it stands for.
    pub last_sample: u32,
    /// See `last_sample`.
    pub last_fraction: f32,
    /// The frame's opacity threshold.
    pub ert_threshold: f32,
}

impl<T: Sample> GatherRay<'_, '_, T> {
    /// Samples `first..end` into `acc`, front to back; `Some(k)` when the ray
    /// reached the opacity threshold with sample `k − 1`.
    ///
    /// Only called on a CPU with AVX2 ([`GatherBrick::new`] checked).
    #[inline(always)]
    pub(crate) fn march_run(&self, acc: &mut Accumulation, first: u32, end: u32) -> Option<u32> {
        let entries = self.table.entries();
        let mut indices = [0i32; GATHER_LANES];
        let mut local = [[0f32; GATHER_LANES]; 3];
        let mut k = first;
        while k < end {
            let n = (end - k).min(GATHER_LANES as u32) as usize;
            #[cfg(target_arch = "x86_64")]
            #[allow(unsafe_code)]
            // SAFETY: `GatherBrick::new` checked that this CPU has AVX2.
            let (outside, mut visible) =
                unsafe { x86::chunk_indices(self, k, n, &mut indices, &mut local) };
            #[cfg(not(target_arch = "x86_64"))]
            let (outside, mut visible): (u32, u32) = unreachable!("no gather layout off x86-64");
            if outside != 0 {
                visible |= self.indices_outside_cells(outside, &local, &mut indices);
            }
            // The visible samples (opacity above 0: what the scalar `Dvr`
            // composites), in order.
            while visible != 0 {
                let j = visible.trailing_zeros() as usize;
                visible &= visible - 1;
                let [r, g, b, a] = entries[indices[j] as usize];
                let sample = k + j as u32;
                let fraction = if sample == self.last_sample {
                    self.last_fraction
                } else {
                    1.0
                };
                over(
                    &mut acc.color,
                    &mut acc.alpha,
                    [r, g, b],
                    partial_step(a, fraction),
                );
                if acc.alpha >= self.ert_threshold {
                    return Some(sample + 1);
                }
            }
            k += n as u32;
        }
        None
    }

    /// The table indices of the lanes in `outside` (a bit per lane), whose
    /// positions lie on no cell of the brick (its upper face): each from
    /// [`BrickSampler::value_local`], as the scalar kernel reads them. Returns
    /// those of them that are visible.
    #[cold]
    fn indices_outside_cells(
        &self,
        outside: u32,
        local: &[[f32; GATHER_LANES]; 3],
        indices: &mut [i32; GATHER_LANES],
    ) -> u32 {
        let mut visible = 0;
        for (j, index) in indices.iter_mut().enumerate() {
            if outside & (1 << j) != 0 {
                let l = glam::Vec3::new(local[0][j], local[1][j], local[2][j]);
                let i = self.table.index(self.sampler.value_local(l));
                *index = i as i32;
                if self.table.entries()[i][3] > 0.0 {
                    visible |= 1 << j;
                }
            }
        }
        visible
    }
}

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
mod x86 {
    use std::arch::x86_64::*;

    use super::{GATHER_LANES, GatherRay};
    use crate::render::transfer::TABLE_SIZE;
    use crate::volume::Sample;

    /// The table indices of samples `k..k + n` (`n ≤ 8`) into `indices` and
    /// their brick-local positions into `local`; returns the lanes (below `n`)
    /// whose position lies on none of the brick's cells, whose indices are
    /// left to the caller, and the other lanes below `n` whose entry's opacity
    /// is above 0.
    ///
    /// # Safety
    /// The CPU has AVX2.
    #[inline]
    #[target_feature(enable = "avx2")]
    pub(super) unsafe fn chunk_indices<T: Sample>(
        ray: &GatherRay<'_, '_, T>,
        k: u32,
        n: usize,
        indices: &mut [i32; GATHER_LANES],
        local: &mut [[f32; GATHER_LANES]; 3],
    ) -> (u32, u32) {
        let brick = &ray.brick;
        let (start, step, last) = ray.positions.parts();
        let zero = _mm256_setzero_ps();
        // Sample numbers as floats (exact: below 2^24), as `k as f32`.
        let ks = _mm256_add_epi32(
            _mm256_set1_epi32(k as i32),
            _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7),
        );
        let kf = _mm256_cvtepi32_ps(ks);
        // Lanes below `n`.
        let used = _mm256_cmpgt_epi32(
            _mm256_set1_epi32(n as i32),
            _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7),
        );
        let mut in_cell = _mm256_castsi256_ps(used);
        let mut fraction = [zero; 3];
        let mut offset = _mm256_setzero_si256();
        for a in 0..3 {
            // `(start + step·k).clamp(0, last)`, then local, floor and fraction.
            let p = _mm256_add_ps(
                _mm256_set1_ps(start[a]),
                _mm256_mul_ps(_mm256_set1_ps(step[a]), kf),
            );
            let p = _mm256_min_ps(_mm256_max_ps(p, zero), _mm256_set1_ps(last[a]));
            let l = _mm256_sub_ps(p, _mm256_set1_ps(brick.origin[a]));
            // SAFETY: `local[a]` holds eight `f32`s; an unaligned store.
            unsafe { _mm256_storeu_ps(local[a].as_mut_ptr(), l) };
            let lower = _mm256_floor_ps(l);
            fraction[a] = _mm256_sub_ps(l, lower);
            let inside = _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_GE_OQ>(lower, zero),
                _mm256_cmp_ps::<_CMP_LE_OQ>(lower, _mm256_set1_ps(brick.max_cell[a])),
            );
            in_cell = _mm256_and_ps(in_cell, inside);
            let cell = _mm256_cvttps_epi32(lower);
            offset = _mm256_add_epi32(
                offset,
                _mm256_mullo_epi32(cell, _mm256_set1_epi32(brick.strides[a])),
            );
        }
        let in_cell_bits = _mm256_movemask_ps(in_cell) as u32;
        let outside = !in_cell_bits & ((1u32 << n) - 1);
        let mask = _mm256_castps_si256(in_cell);
        // Lanes not in a cell read nothing (masked), so their offsets need no
        // bound; the others' corners lie in the slice.
        let offset = _mm256_and_si256(offset, mask);
        let base = brick.bytes.as_ptr() as *const i32;
        let value_mask = _mm256_set1_epi32(if brick.sample_size == 1 { 0xff } else { 0xffff });
        let far = brick.corners[7];
        let near_end = _mm256_movemask_epi8(_mm256_cmpgt_epi32(
            offset,
            _mm256_set1_epi32(brick.last_whole_read - far),
        )) != 0;
        let corner = |c: usize, near_end: bool| -> __m256 {
            let at = _mm256_add_epi32(offset, _mm256_set1_epi32(brick.corners[c]));
            let (at, shift) = if near_end {
                // A four-byte read that would pass the slice's end reads the
                // four bytes ending with the sample instead (the slice holds at
                // least eight), its sample in the high bytes.
                let over = _mm256_cmpgt_epi32(at, _mm256_set1_epi32(brick.last_whole_read));
                let back = _mm256_and_si256(over, _mm256_set1_epi32(4 - brick.sample_size));
                (_mm256_sub_epi32(at, back), _mm256_slli_epi32::<3>(back))
            } else {
                (at, _mm256_setzero_si256())
            };
            // SAFETY: each lane of `mask` reads four bytes at `base + at`, with
            // `0 ≤ at ≤ len − 4`: the corner's sample lies in the slice (as the
            // scalar `BrickSampler::corners` indexes it), and an `at` past
            // `len − 4` was moved back by `4 − size` bytes, still at or above 0
            // (the slice has at least 8 bytes, the sample at least 4 − size from
            // its start then). The CPU has AVX2 (this function's contract).
            let words =
                unsafe { _mm256_mask_i32gather_epi32::<1>(_mm256_setzero_si256(), base, at, mask) };
            _mm256_cvtepi32_ps(_mm256_and_si256(
                _mm256_srlv_epi32(words, shift),
                value_mask,
            ))
        };
        // (Two copies, each with its `near_end` a constant.)
        let c: [__m256; 8] = if near_end {
            std::array::from_fn(|i| corner(i, true))
        } else {
            std::array::from_fn(|i| corner(i, false))
        };
        let [fx, fy, fz] = fraction;
        let lerp = |a: __m256, b: __m256, t: __m256| {
            _mm256_add_ps(a, _mm256_mul_ps(_mm256_sub_ps(b, a), t))
        };
        // `trilinear`: z, then y, then x.
        let c00 = lerp(c[0], c[1], fz);
        let c01 = lerp(c[2], c[3], fz);
        let c10 = lerp(c[4], c[5], fz);
        let c11 = lerp(c[6], c[7], fz);
        let value = lerp(lerp(c00, c01, fy), lerp(c10, c11, fy), fx);
        // `TransferTable::index`: `(v − offset)·scale + 0.5`, clamped, truncated.
        let (table_offset, table_scale) = ray.table.index_map();
        let x = _mm256_add_ps(
            _mm256_mul_ps(
                _mm256_sub_ps(value, _mm256_set1_ps(table_offset)),
                _mm256_set1_ps(table_scale),
            ),
            _mm256_set1_ps(0.5),
        );
        // `max` first with `x` as its first operand: NaN becomes 0, as
        // `truncate_clamped`.
        let x = _mm256_min_ps(
            _mm256_max_ps(x, zero),
            _mm256_set1_ps((TABLE_SIZE - 1) as f32),
        );
        let index = _mm256_cvttps_epi32(x);
        // SAFETY: `indices` holds eight `i32`s; an unaligned store.
        unsafe { _mm256_storeu_si256(indices.as_mut_ptr() as *mut __m256i, index) };
        // The entries' opacities: element `4·index + 3` of the table as floats.
        let entries = ray.table.entries();
        debug_assert_eq!(entries.len(), TABLE_SIZE);
        // SAFETY: each lane of `in_cell` reads the opacity of entry `index`,
        // which the clamp above keeps in `0..TABLE_SIZE`, the table's length
        // (`march_dvr_chunks` gathers only from such tables). The CPU has AVX2.
        let alpha = unsafe {
            _mm256_mask_i32gather_ps::<4>(
                zero,
                entries.as_ptr().cast::<f32>().add(3),
                _mm256_slli_epi32::<2>(index),
                in_cell,
            )
        };
        let visible = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(alpha, zero)) as u32;
        (outside, visible & in_cell_bits)
    }
}

#[cfg(test)]
mod tests {
    use glam::{Vec3, Vec3A};

    use super::*;
    use crate::render::TransferFunction;
    use crate::render::test_rng::xorshift32;
    use crate::volume::BrickView;

    /// The scalar kernel's loop for samples `first..end`: `value_local`, the
    /// table, `over`, the threshold.
    fn scalar_run<T: Sample>(
        ray: &GatherRay<'_, '_, T>,
        acc: &mut Accumulation,
        first: u32,
        end: u32,
    ) -> Option<u32> {
        for k in first..end {
            let l = Vec3::from(ray.positions.at(k)) - ray.sampler.origin();
            let [r, g, b, a] = ray.table.lookup(ray.sampler.value_local(l));
            if a <= 0.0 {
                continue;
            }
            let fraction = if k == ray.last_sample {
                ray.last_fraction
            } else {
                1.0
            };
            over(
                &mut acc.color,
                &mut acc.alpha,
                [r, g, b],
                partial_step(a, fraction),
            );
            if acc.alpha >= ray.ert_threshold {
                return Some(k + 1);
            }
        }
        None
    }

    /// Random rays through a brick whose samples end exactly at its slice's end
    /// (the reads moved back), rays along its upper faces (samples on no cell),
    /// partial chunks and last samples: the gathers give the scalar loop's bits.
    fn gathers_equal_the_scalar_loop<T: Sample>(to_sample: impl Fn(u32) -> T, type_max: u16) {
        if GatherBrick::new(&BrickSampler::new(BrickView::dense(
            &[to_sample(0); 8],
            [0; 3],
            [2, 2, 2],
        )))
        .is_none()
        {
            #[cfg(target_arch = "x86_64")]
            assert!(
                !std::is_x86_feature_detected!("avx2"),
                "AVX2 but no gathers"
            );
            return;
        }
        let extent = [9u32, 7, 12];
        let origin = [16u32, 3, 40];
        let mut next = xorshift32(0x9e37_79b9);
        let samples: Vec<T> = (0..extent.iter().product::<u32>())
            .map(|_| to_sample(next()))
            .collect();
        let sampler = BrickSampler::new(BrickView::dense(&samples, origin, extent));
        let brick = GatherBrick::new(&sampler).expect("gather layout");
        let tf = TransferFunction::preset("shapes").unwrap();
        let table = TransferTable::new(&tf, type_max, 0.4);
        let o = Vec3A::from(sampler.origin());
        let far = Vec3A::from(extent.map(|e| (e - 1) as f32));
        let mut unit = || (next() % 1_000_001) as f32 / 1_000_000.0;
        let (mut compared, mut visible, mut stopped) = (0, 0, 0);
        for round in 0..3_000 {
            // A start inside the brick, or on one of its upper faces.
            let mut start = Vec3A::new(unit(), unit(), unit()) * far;
            let mut dir = Vec3A::new(unit() - 0.5, unit() - 0.5, unit() - 0.5);
            if round % 5 == 0 {
                let axis = round / 5 % 3;
                start[axis] = far[axis];
                dir[axis] = 0.0;
            }
            if round % 7 == 0 {
                // Towards the brick's last voxel, whose cell reads end the slice.
                dir = far - start;
            }
            let step = dir.normalize_or_zero() * (0.05 + unit() * 0.6);
            // Samples while the position stays in the brick.
            let count = (0..400u32)
                .take_while(|&k| {
                    let p = start + step * k as f32;
                    p.cmpge(Vec3A::ZERO).all() && p.cmple(far).all()
                })
                .count() as u32;
            if count == 0 {
                continue;
            }
            let ray = GatherRay {
                brick,
                sampler: &sampler,
                table: &table,
                positions: SamplePositions::new(start + o, step, o + far),
                last_sample: count - 1,
                last_fraction: 0.25 + unit() * 0.5,
                ert_threshold: if round % 2 == 0 { f32::INFINITY } else { 0.9 },
            };
            let first = ((unit() * 11.0) as u32).min(count - 1);
            let (mut a, mut b) = (
                Accumulation::starting_at(0.0),
                Accumulation::starting_at(0.0),
            );
            let gathered = ray.march_run(&mut a, first, count);
            let scalar = scalar_run(&ray, &mut b, first, count);
            assert_eq!(gathered, scalar, "round {round}");
            assert_eq!(a.alpha.to_bits(), b.alpha.to_bits(), "round {round}");
            assert_eq!(
                a.color.map(f32::to_bits),
                b.color.map(f32::to_bits),
                "round {round}"
            );
            compared += count - first;
            visible += u32::from(b.alpha > 0.0);
            stopped += u32::from(scalar.is_some());
        }
        assert!(
            compared > 40_000 && visible > 500 && stopped > 100,
            "{compared} {visible} {stopped}"
        );
    }

    #[test]
    fn u8_gathers_equal_the_scalar_loop() {
        gathers_equal_the_scalar_loop(|r| (r >> 7) as u8, 255);
    }

    #[test]
    fn u16_gathers_equal_the_scalar_loop() {
        gathers_equal_the_scalar_loop(|r| (r >> 5) as u16, u16::MAX);
    }
}
