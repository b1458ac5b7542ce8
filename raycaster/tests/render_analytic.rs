//! The reference ray caster against answers known in closed form.

mod render_support;

use raycaster::render::{Camera, Mode, ModeParameters, Projection, Ray, Vec3, corrected_alpha};
use render_support::*;

/// Orthographic camera looking along +x at the volume's middle.
fn along_x(volume: &raycaster::volume::Volume, size: u32) -> Camera {
    let c = centre(volume);
    Camera::new(
        Vec3::new(-10.0, c.y, c.z),
        Vec3::X,
        Vec3::Z,
        Projection::Orthographic { height: 4.0 },
        size,
        size,
    )
    .unwrap()
}

#[test]
fn homogeneous_slab_gives_the_closed_form_opacity() {
    // 17 voxels along x at spacing 1.5: a slab 24 world units thick; one reference
    // step is one voxel of the smallest spacing (1.0, on y and z).
    let volume = volume_u8([17, 9, 9], [1.5, 1.0, 1.0], |_, _, _| 200);
    let alpha0 = 0.05;
    let tf = white_tf(&[(0.0, alpha0), (1.0, alpha0)]);
    for step in [0.5, 0.3, 0.7, 1.0] {
        let settings = plain_settings(tf.clone());
        let settings = raycaster::render::RenderSettings { step, ..settings };
        let frame = render(&volume, &along_x(&volume, 8), &settings);
        let expected = 1.0 - (1.0f32 - alpha0).powf(24.0);
        for px in &frame.rgba {
            assert!(
                (px[3] - expected).abs() < 1e-3,
                "step {step}: alpha {} expected {expected}",
                px[3]
            );
        }
    }
}

#[test]
fn xray_of_a_homogeneous_slab_sums_its_thickness_at_every_step() {
    // The slab above: 24 reference steps thick. Each sample weighs the part of
    // a step it stands for, the ray's last (partial) one too, so the sum is the
    // thickness times the normalised value whatever the step (a last sample
    // weighing a whole step added up to 0.7 at step 0.7).
    let volume = volume_u8([17, 9, 9], [1.5, 1.0, 1.0], |_, _, _| 200);
    let tf = white_tf(&[(0.0, 1.0), (1.0, 1.0)]);
    let gain = 0.05;
    for step in [0.5, 0.3, 0.7, 1.0, 1.7] {
        let settings = raycaster::render::RenderSettings {
            step,
            mode: Mode::XRay,
            mode_parameters: ModeParameters {
                xray_gain: Some(gain),
                ..ModeParameters::default()
            },
            ..plain_settings(tf.clone())
        };
        let frame = render(&volume, &along_x(&volume, 8), &settings);
        let expected = 1.0 - (-gain * 200.0 / 255.0 * 24.0f32).exp();
        for px in &frame.rgba {
            assert!(
                (px[3] - expected).abs() < 1e-4,
                "step {step}: alpha {} expected {expected}",
                px[3]
            );
        }
    }
}

#[test]
fn slab_opacity_follows_each_perspective_rays_length() {
    let volume = volume_u8([20, 20, 20], [1.0, 1.0, 1.0], |_, _, _| 255);
    let alpha0 = 0.02;
    let tf = white_tf(&[(0.0, alpha0), (1.0, alpha0)]);
    let camera = Camera::look_at(
        Vec3::new(-15.0, 4.0, 25.0),
        centre(&volume),
        Vec3::Z,
        Projection::Perspective { vfov_deg: 50.0 },
        24,
        24,
    )
    .unwrap();
    let coarse = render(&volume, &camera, &plain_settings(tf.clone()));
    let fine_settings = raycaster::render::RenderSettings {
        step: 0.25,
        ..plain_settings(tf)
    };
    let fine = render(&volume, &camera, &fine_settings);
    let (lo, hi) = (Vec3::ZERO, Vec3::splat(19.0));
    let mut hits = 0;
    for y in 0..24 {
        for x in 0..24 {
            let i = coarse.index(x, y);
            let ray: Ray = camera.ray(x, y);
            let expected = match ray.intersect_box(lo, hi) {
                Some((t0, t1)) => 1.0 - (1.0f32 - alpha0).powf(t1 - t0),
                None => 0.0,
            };
            hits += usize::from(expected > 0.0);
            assert!((coarse.rgba[i][3] - expected).abs() < 1e-3, "pixel {x},{y}");
            // Halving the step (0.5 → 0.25) leaves the opacity where it was.
            assert!(
                (fine.rgba[i][3] - coarse.rgba[i][3]).abs() < 1e-2,
                "pixel {x},{y}"
            );
        }
    }
    assert!(hits > 100, "the camera must see the volume ({hits} hits)");
}

#[test]
fn opacity_correction_keeps_a_textured_volume_stable_across_steps() {
    // Not homogeneous: the alpha varies along the ray, still nearly step-independent.
    let volume = volume_u8([24, 24, 24], [1.0; 3], |x, y, z| {
        ((x * 7 + y * 3 + z * 5) % 256) as u8
    });
    let tf = white_tf(&[(0.0, 0.0), (1.0, 0.08)]);
    let camera = along_x(&volume, 16);
    let half = render(&volume, &camera, &plain_settings(tf.clone()));
    let quarter_settings = raycaster::render::RenderSettings {
        step: 0.25,
        ..plain_settings(tf)
    };
    let quarter = render(&volume, &camera, &quarter_settings);
    for (a, b) in half.rgba.iter().zip(&quarter.rgba) {
        assert!((a[3] - b[3]).abs() < 1e-2, "{} vs {}", a[3], b[3]);
    }
}

#[test]
fn mip_finds_the_known_maximum() {
    // Background 50, a 5³ plateau of 240 in the middle.
    let volume = volume_u8([21, 21, 21], [1.0; 3], |x, y, z| {
        if [x, y, z].iter().all(|&c| (8..=12).contains(&c)) {
            240
        } else {
            50
        }
    });
    // Grey = value, fully opaque: the pixel shows the maximum.
    let mut tf = white_tf(&[(0.0, 1.0), (1.0, 1.0)]);
    tf = raycaster::render::TransferFunction::new(
        tf.points()
            .iter()
            .map(|p| raycaster::render::ControlPoint {
                color: [p.value; 3],
                ..*p
            })
            .collect(),
    )
    .unwrap();
    let settings = raycaster::render::RenderSettings {
        mode: Mode::Mip,
        ..plain_settings(tf)
    };
    let camera = Camera::new(
        Vec3::new(-10.0, 10.0, 10.0),
        Vec3::X,
        Vec3::Z,
        Projection::Orthographic { height: 20.0 },
        21,
        21,
    )
    .unwrap();
    let frame = render(&volume, &camera, &settings);
    let resolution = 1.0 / 1023.0;
    let centre_px = frame.rgba[frame.index(10, 10)];
    assert!(
        (centre_px[0] - 240.0 / 255.0).abs() <= resolution,
        "{centre_px:?}"
    );
    let corner_px = frame.rgba[frame.index(1, 1)];
    assert!(
        (corner_px[0] - 50.0 / 255.0).abs() <= resolution,
        "{corner_px:?}"
    );
    // Average mode: a ray missing the plateau averages exactly the background.
    let avg = raycaster::render::RenderSettings {
        mode: Mode::Average,
        ..settings
    };
    let frame = render(&volume, &camera, &avg);
    let corner_px = frame.rgba[frame.index(1, 1)];
    assert!(
        (corner_px[0] - 50.0 / 255.0).abs() <= resolution,
        "{corner_px:?}"
    );
    let centre_px = frame.rgba[frame.index(10, 10)];
    assert!(centre_px[0] > 60.0 / 255.0 && centre_px[0] < 240.0 / 255.0);
}

#[test]
fn first_hit_finds_the_known_surface_depth() {
    // value = 5·x: the iso-value 0.5 (127.5) lies at x = 25.5 voxels = 51 world units.
    let volume = volume_u8([51, 12, 12], [2.0, 1.0, 1.0], |x, _, _| (5 * x) as u8);
    let settings = raycaster::render::RenderSettings {
        mode: Mode::FirstHit,
        iso_value: 0.5,
        ..plain_settings(white_tf(&[(0.0, 1.0), (1.0, 1.0)]))
    };
    let ortho = along_x(&volume, 6);
    let frame = render(&volume, &ortho, &settings);
    for (i, d) in frame.depth.iter().enumerate() {
        assert!((d - (51.0 + 10.0)).abs() < 1e-3, "pixel {i}: depth {d}");
        assert_eq!(frame.rgba[i][3], 1.0);
    }
    // Perspective: the depth along each ray to the plane x = 51.
    let eye = Vec3::new(-7.0, 3.0, 8.0);
    let persp = Camera::look_at(
        eye,
        centre(&volume),
        Vec3::Z,
        Projection::Perspective { vfov_deg: 20.0 },
        16,
        16,
    )
    .unwrap();
    let frame = render(&volume, &persp, &settings);
    let mut hits = 0;
    for y in 0..16 {
        for x in 0..16 {
            let ray = persp.ray(x, y);
            let t = (51.0 - eye.x) / ray.direction.x;
            let p = ray.at(t);
            let inside = p.y >= 0.0 && p.y <= 11.0 && p.z >= 0.0 && p.z <= 11.0;
            let d = frame.depth[frame.index(x, y)];
            if inside && p.y > 0.5 && p.y < 10.5 && p.z > 0.5 && p.z < 10.5 {
                hits += 1;
                assert!(
                    (d - t).abs() < 1e-2,
                    "pixel {x},{y}: depth {d}, expected {t}"
                );
            } else if !inside {
                assert!(d.is_infinite(), "pixel {x},{y} should miss the surface");
            }
        }
    }
    assert!(hits > 20, "{hits} hits");
}

#[test]
fn a_missing_ray_leaves_the_background_exactly() {
    let volume = volume_u8([16, 16, 16], [1.0; 3], |_, _, _| 255);
    let background = [12.0 / 255.0, 200.0 / 255.0, 77.0 / 255.0];
    let settings = raycaster::render::RenderSettings {
        background,
        ..plain_settings(white_tf(&[(0.0, 1.0), (1.0, 1.0)]))
    };
    let camera = Camera::look_at(
        Vec3::new(-30.0, 7.5, 7.5),
        centre(&volume),
        Vec3::Z,
        Projection::Perspective { vfov_deg: 60.0 },
        32,
        32,
    )
    .unwrap();
    for mode in Mode::ALL {
        let s = raycaster::render::RenderSettings {
            mode,
            ..settings.clone()
        };
        let frame = render(&volume, &camera, &s);
        let image = frame.to_image();
        assert_eq!(image.pixel(0, 0), [12, 200, 77], "{mode:?}");
        assert_eq!(image.pixel(31, 31), [12, 200, 77], "{mode:?}");
        // Context-preserving rendering keeps only where the gradient is strong:
        // nothing of a homogeneous volume.
        if mode != Mode::ContextPreserving {
            assert_ne!(
                image.pixel(16, 16),
                [12, 200, 77],
                "{mode:?}: the volume is in view"
            );
        }
    }
    // Looking away from the volume: nothing is cast, the whole image is background.
    let away = Camera::new(
        Vec3::new(-30.0, 7.5, 7.5),
        -Vec3::X,
        Vec3::Z,
        Projection::Perspective { vfov_deg: 60.0 },
        8,
        8,
    )
    .unwrap();
    let frame = render(&volume, &away, &settings);
    assert_eq!(frame.stats.counters.rays, 0);
    assert!(
        frame
            .to_image()
            .data()
            .chunks(3)
            .all(|p| p == [12, 200, 77])
    );
}

#[test]
fn corrected_alpha_is_the_thesis_formula() {
    for (a0, r) in [(0.3f32, 0.5f32), (0.9, 0.2), (0.01, 3.0)] {
        assert!((corrected_alpha(a0, r) - (1.0 - (1.0 - a0).powf(r))).abs() < 1e-7);
    }
}

/// An 8-bit ramp across the view, lit by the headlight from the side of its
/// gradient (ambient only where shaded): its central differences alternate
/// between just below and just above the shading threshold (2 or 3 levels of
/// 255 per two voxels: 0.0098 and 0.0118). Shading fades in above the
/// threshold, so neighbouring pixels differ by little; a hard switch drew
/// stripes of unshaded and ambient-lit colour (neighbours 178 levels apart; 6 over a fade of 3 times the threshold).
#[test]
fn an_eight_bit_ramp_near_the_shading_threshold_renders_without_stripes() {
    let n = 100u32;
    let volume = volume_u8([n, 24, 24], [1.0; 3], |x, _, _| {
        (x as f32 * 255.0 / (n - 1) as f32) as u8
    });
    let c = centre(&volume);
    // Looking along +z, x across the image.
    let camera = Camera::new(
        Vec3::new(c.x, c.y, -10.0),
        Vec3::Z,
        Vec3::Y,
        Projection::Orthographic { height: 110.0 },
        200,
        200,
    )
    .unwrap();
    let settings = raycaster::render::RenderSettings {
        shading: Some(raycaster::render::Shading::default()),
        ..plain_settings(white_tf(&[(0.0, 0.3), (1.0, 0.3)]))
    };
    let frame = render(&volume, &camera, &settings);
    let row: Vec<f32> = (0..200).map(|i| frame.rgba[100 * 200 + i][0]).collect();
    // The ramp's inside, away from its ends (where the gradient is one-sided).
    let inside = &row[30..170];
    let jump = inside
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .fold(0.0f32, f32::max);
    assert!(inside.iter().all(|&v| v > 0.1), "{inside:?}");
    assert!(
        jump < 10.0 / 255.0,
        "neighbours differ by {}/255",
        jump * 255.0
    );
}
