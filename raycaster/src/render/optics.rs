//! The optics every compositor shares, written once: the front-to-back "over"
//! step, opacity correction for a fraction of a step, smoothstep, light and half
//! vectors, and the importance-aware compositing step.

use std::ops::Mul;

use glam::{Vec3, Vec4};

use super::shading::{Light, Shading};

/// Opacity `alpha0` (per reference step) corrected for `ratio` reference steps:
/// `α = 1 − (1 − α0)^ratio`. Also the correction of a ray's last, partial step
/// (`ratio` = the fraction of a step it stands for).
#[inline]
pub fn corrected_alpha(alpha0: f32, ratio: f32) -> f32 {
    if alpha0 >= 1.0 {
        1.0
    } else {
        1.0 - (1.0 - alpha0).powf(ratio)
    }
}

/// Opacity `a` of a sample that stands for `fraction` of a step (1 for every
/// sample but a ray's last).
#[inline]
pub(crate) fn partial_step(a: f32, fraction: f32) -> f32 {
    if fraction < 1.0 {
        corrected_alpha(a, fraction)
    } else {
        a
    }
}

/// The front-to-back "over" step: `c += (1 − α)·a·color; α += (1 − α)·a`.
#[inline]
pub(crate) fn over(acc_color: &mut [f32; 3], acc_alpha: &mut f32, color: [f32; 3], a: f32) {
    let w = (1.0 - *acc_alpha) * a;
    for (acc, c) in acc_color.iter_mut().zip(color) {
        *acc += w * c;
    }
    *acc_alpha += w;
}

/// The "over" step of DVR sample `k` of a ray whose last sample `last` stands
/// for `fraction` of a step ([`partial_step`]); whether the opacity reached
/// `threshold` after it (the SIMD kernels' compositing, the scalar `Dvr`'s
/// bits).
#[inline(always)]
pub(crate) fn over_sample(
    acc_color: &mut [f32; 3],
    acc_alpha: &mut f32,
    (color, a): ([f32; 3], f32),
    k: u32,
    (last, fraction): (u32, f32),
    threshold: f32,
) -> bool {
    let fraction = if k == last { fraction } else { 1.0 };
    over(acc_color, acc_alpha, color, partial_step(a, fraction));
    *acc_alpha >= threshold
}

/// The "over" step of a premultiplied colour `color` with opacity `a` (a
/// segment's result): `c += (1 − α)·color; α += (1 − α)·a`.
#[inline]
pub(crate) fn over_premultiplied(
    acc_color: &mut [f32; 3],
    acc_alpha: &mut f32,
    color: [f32; 3],
    a: f32,
) {
    let w = 1.0 - *acc_alpha;
    for (acc, c) in acc_color.iter_mut().zip(color) {
        *acc += w * c;
    }
    *acc_alpha += w * a;
}

/// `smoothstep(e0, e1, x)`: 0 below `e0`, 1 above `e1`, a cubic between.
#[inline]
pub(crate) fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// `x^e` for the specular term, `x` in `[0, 1]`: by repeated squaring when `e` is a
/// whole number up to 255 (the usual shininess; a few multiplications instead of a
/// `powf` call), else `powf`.
#[inline]
pub(crate) fn specular_power(x: f32, e: f32) -> f32 {
    match whole_exponent(e) {
        Some(n) => power_by_squaring(x, 1.0, n),
        None => x.powf(e),
    }
}

/// [`specular_power`] of four values at once, each lane with its operations.
#[inline]
pub(crate) fn specular_power_lanes(x: Vec4, e: f32) -> Vec4 {
    match whole_exponent(e) {
        Some(n) => power_by_squaring(x, Vec4::ONE, n),
        None => Vec4::from_array(x.to_array().map(|x| x.powf(e))),
    }
}

/// `x^n` by repeated squaring (`one` is 1 of `x`'s type).
#[inline(always)]
fn power_by_squaring<V: Copy + Mul<Output = V>>(x: V, one: V, mut n: u32) -> V {
    let (mut base, mut out) = (x, one);
    while n > 0 {
        if n & 1 == 1 {
            out = out * base;
        }
        base = base * base;
        n >>= 1;
    }
    out
}

/// `e` as a whole number, if it is one from 0 to 255: the exponents
/// [`specular_power`] takes by repeated squaring. (`e as u32` saturates, and NaN
/// gives 0, so the round trip holds only for whole numbers; no `fract`, which
/// is a library call where the compiler does not hoist it.)
#[inline]
pub(crate) fn whole_exponent(e: f32) -> Option<u32> {
    let n = e as u32;
    (n as f32 == e && e <= 255.0).then_some(n)
}

/// Unit vectors towards the light and halfway between it and the eye, for a ray
/// of unit direction `view_dir` (the headlight when `light` is `None`).
#[inline]
pub(crate) fn light_vectors(light: Option<Light>, view_dir: Vec3) -> (Vec3, Vec3) {
    match light {
        Some(Light::Fixed(d)) => {
            let to_light = -d.normalize_or_zero();
            (to_light, (to_light - view_dir).normalize_or_zero())
        }
        // A headlight: the half vector is the light vector itself.
        _ => (-view_dir, -view_dir),
    }
}

/// Blinn-Phong intensity `c_d|L·N| + c_s|H·N|^c_e + c_a` at gradient `gradient`
/// (1 without shading).
pub(crate) fn shading_intensity(shading: Option<&Shading>, gradient: Vec3, view_dir: Vec3) -> f32 {
    let Some(sh) = shading else { return 1.0 };
    let n = gradient.normalize_or_zero();
    let (l, h) = light_vectors(Some(sh.light), view_dir);
    sh.diffuse * n.dot(l).abs()
        + sh.specular * specular_power(n.dot(h).abs(), sh.shininess)
        + sh.ambient
}

/// One step of importance-aware compositing (de Moura Pinto & Freitas) of a
/// sample with premultiplied colour `cs`, opacity `a_s` and importance `i_s` into
/// the accumulation `(c_i, a_i, i_i)`:
/// `vis = 1 − exp(I_i − I_s)`; `m = 1` if `I_s ≤ I_i` or `1 − α_i ≥ vis`, else
/// `(1 − vis)/α_i`; `C' = m·C_i + (1 − m·α_i)·C_s`; `α' = m·α_i(1 − α_s) + α_s`;
/// `α_{i+1} = α_i(1 − α_s) + α_s`; `C_{i+1} = α_{i+1}·C'/α'`;
/// `I_{i+1} = max(I_i, ln(α_s + (1 − α_s)·exp(I_i − I_s)) + I_s)`.
pub fn importance_composite(
    c_i: [f32; 3],
    a_i: f32,
    i_i: f32,
    c_s: [f32; 3],
    a_s: f32,
    i_s: f32,
) -> ([f32; 3], f32, f32) {
    let vis = 1.0 - (i_i - i_s).exp();
    let m = if i_s <= i_i || 1.0 - a_i >= vis {
        1.0
    } else {
        (1.0 - vis) / a_i
    };
    let a_mod = m * a_i * (1.0 - a_s) + a_s;
    let a_next = a_i * (1.0 - a_s) + a_s;
    let c_next = if a_mod == 0.0 {
        [0.0; 3]
    } else {
        [0, 1, 2].map(|k| a_next * (m * c_i[k] + (1.0 - m * a_i) * c_s[k]) / a_mod)
    };
    let i_next = i_i.max((a_s + (1.0 - a_s) * (i_i - i_s).exp()).ln() + i_s);
    (c_next, a_next, i_next)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn whole_exponents_are_the_whole_numbers_from_0_to_255() {
        let old_rule = |e: f32| (0.0..=255.0).contains(&e) && e.fract() == 0.0;
        for e in [
            0.0,
            -0.0,
            1.0,
            24.0,
            255.0,
            256.0,
            255.5,
            0.5,
            -1.0,
            7.5,
            4_294_967_296.0,
            1e20,
            f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
        ] {
            assert_eq!(whole_exponent(e).is_some(), old_rule(e), "{e}");
        }
        for n in 0..=300u32 {
            let e = n as f32;
            assert_eq!(whole_exponent(e), old_rule(e).then_some(n), "{e}");
            let (squared, pow) = (specular_power(0.9, e), 0.9f32.powf(e));
            assert!(
                (squared - pow).abs() <= 1e-5 * pow.max(1e-30),
                "{e}: {squared} {pow}"
            );
        }
    }

    #[test]
    fn importance_at_or_below_the_accumulated_one_is_plain_compositing() {
        let (ci, ai) = ([0.2, 0.1, 0.05], 0.4);
        let (cs, a_s) = ([0.3, 0.3, 0.3], 0.5);
        let (c, a, i) = importance_composite(ci, ai, 2.0, cs, a_s, 1.5);
        for k in 0..3 {
            assert!((c[k] - (ci[k] + (1.0 - ai) * cs[k])).abs() < 1e-6);
        }
        assert!((a - (ai + (1.0 - ai) * a_s)).abs() < 1e-6);
        assert!(i >= 2.0);
    }

    #[test]
    fn an_opaque_sample_sets_the_importance_and_a_more_important_one_shows_through() {
        let (_, a, i) = importance_composite([0.5; 3], 0.9, 0.2, [0.1; 3], 1.0, 3.0);
        assert!((i - 3.0).abs() < 1e-6, "{i}");
        assert!((a - 1.0).abs() < 1e-6);
        // A more important sample behind a dense, unimportant front: its colour
        // weighs more than plain compositing would give it.
        let (c, _, _) = importance_composite([0.9, 0.0, 0.0], 0.9, 0.0, [0.0, 0.5, 0.0], 0.5, 5.0);
        let plain = 0.1 * 0.5;
        assert!(c[1] > plain * 2.0, "{c:?}");
    }

    #[test]
    fn the_specular_power_equals_powf() {
        for e in [0.0, 1.0, 2.0, 7.0, 24.0, 100.0, 2.5, 300.0] {
            for x in [0.0f32, 0.1, 0.5, 0.9, 0.999, 1.0] {
                let (fast, exact) = (specular_power(x, e), x.powf(e));
                assert!(
                    (fast - exact).abs() <= 1e-5 * exact.max(1e-3),
                    "{x}^{e}: {fast} {exact}"
                );
            }
        }
    }

    #[test]
    fn a_partial_step_is_the_opacity_of_that_fraction() {
        assert_eq!(partial_step(0.4, 1.0), 0.4);
        let half = partial_step(0.75, 0.5);
        assert!((half - 0.5).abs() < 1e-6, "{half}");
        // Two half steps make the whole one.
        let mut c = [0.0; 3];
        let mut a = 0.0;
        over(&mut c, &mut a, [1.0; 3], half);
        over(&mut c, &mut a, [1.0; 3], half);
        assert!((a - 0.75).abs() < 1e-6, "{a}");
    }
}
