//! Crop boxes and clipping planes against answers known exactly: the thickness a
//! plane leaves of a homogeneous slab, a crop box against the sub-volume it keeps,
//! bricks outside the region left out of the frame.

mod render_support;

use raycaster::render::{
    Camera, ClipPlane, ClipRegion, CropBox, Mode, ParallelOptions, Projection, RenderSettings,
    RenderVolume, Vec3, render_parallel, render_sequential,
};
use raycaster::volume::Volume;
use render_support::*;

/// Orthographic camera at `position` looking along +x, 32 pixels of one world
/// unit each (pixel centres at half units from the camera's axis).
fn along_x(position: Vec3) -> Camera {
    Camera::new(
        position,
        Vec3::X,
        Vec3::Z,
        Projection::Orthographic { height: 32.0 },
        32,
        32,
    )
    .unwrap()
}

fn plane(point: [f32; 3], normal: [f32; 3]) -> ClipPlane {
    ClipPlane {
        point: Vec3::from(point),
        normal: Vec3::from(normal),
    }
}

fn crop(lo: [f32; 3], hi: [f32; 3]) -> Option<CropBox> {
    Some(CropBox {
        lo: Vec3::from(lo),
        hi: Vec3::from(hi),
    })
}

/// Pixels whose rays pass through the middle of a 17×9×9 slab along x.
fn slab_pixels() -> impl Iterator<Item = (u32, u32)> {
    // Pixel (x, y) looks along y = 19.5 − x, z = 19.5 − y: these lie in [1.5, 6.5].
    (13..19).flat_map(|y| (13..19).map(move |x| (x, y)))
}

#[test]
fn a_plane_through_a_homogeneous_slab_leaves_the_analytic_thickness() {
    // 17 voxels along x: the box is x ∈ [0, 16]; rays enter at x = 0 (t = 10).
    let volume = volume_u8([17, 9, 9], [1.0; 3], |_, _, _| 200);
    let camera = along_x(Vec3::new(-10.0, 4.0, 4.0));
    let alpha0 = 0.05;
    let tf = white_tf(&[(0.0, alpha0), (1.0, alpha0)]);
    // Keep x ≥ 4 (plane) and x ≤ 13 (crop): 9 voxels of the 16.
    let clip = ClipRegion {
        crop: crop([-5.0, -5.0, -5.0], [13.0, 20.0, 20.0]),
        planes: vec![plane([4.0, 0.0, 0.0], [2.0, 0.0, 0.0])],
    };
    for step in [0.5, 0.25, 1.0, 0.8] {
        let settings = RenderSettings {
            step,
            clip: clip.clone(),
            ..plain_settings(tf.clone())
        };
        // Emission–absorption: 1 − (1 − α0)^9 whatever the step (the cut's front
        // lies on a sample for these steps; the last kept sample stands for the
        // rest of the region).
        let frame = render(&volume, &camera, &settings);
        let expected = 1.0 - (1.0f32 - alpha0).powf(9.0);
        for (x, y) in slab_pixels() {
            let a = frame.rgba[frame.index(x, y)][3];
            assert!(
                (a - expected).abs() < 1e-4,
                "step {step}: alpha {a}, expected {expected}"
            );
        }
        // X-ray: the sum of normalised values × step is the thickness × 200/255
        // (X-ray sums whole steps: at 0.8 the 12 kept samples stand for 9.6).
        if step == 0.8 {
            continue;
        }
        let xray = RenderSettings {
            mode: Mode::XRay,
            ..settings.clone()
        };
        let frame = render(&volume, &camera, &xray);
        let expected = 1.0 - (-9.0f32 * 200.0 / 255.0).exp();
        for (x, y) in slab_pixels() {
            let a = frame.rgba[frame.index(x, y)][3];
            assert!((a - expected).abs() < 1e-4, "xray step {step}: {a}");
        }
    }
    // Samples keep their places: a cut at x = 4.3 keeps samples from x = 4.5
    // (step 0.5), so 8.5 voxels of the slab, not 8.7.
    let settings = RenderSettings {
        clip: ClipRegion {
            crop: clip.crop,
            planes: vec![plane([4.3, 0.0, 0.0], [1.0, 0.0, 0.0])],
        },
        ..plain_settings(tf.clone())
    };
    let frame = render(&volume, &camera, &settings);
    let expected = 1.0 - (1.0f32 - alpha0).powf(8.5);
    for (x, y) in slab_pixels() {
        let a = frame.rgba[frame.index(x, y)][3];
        assert!(
            (a - expected).abs() < 1e-4,
            "alpha {a}, expected {expected}"
        );
    }
    // A tilted plane: its thickness along each ray follows the plane. The plane
    // x + z = 12 keeps x ≥ 12 − z; a ray at height z crosses 16 − (12 − z) = 4 + z
    // voxels of the slab (to within the step before the first kept sample).
    let settings = RenderSettings {
        step: 0.125,
        clip: ClipRegion {
            crop: None,
            planes: vec![plane([12.0, 0.0, 0.0], [1.0, 0.0, 1.0])],
        },
        ..plain_settings(tf)
    };
    let frame = render(&volume, &camera, &settings);
    for (x, y) in slab_pixels() {
        let ray = camera.ray(x, y);
        let thickness = 4.0 + ray.origin.z;
        let a = frame.rgba[frame.index(x, y)][3];
        let thick = 1.0 - (1.0f32 - alpha0).powf(thickness);
        let thin = 1.0 - (1.0f32 - alpha0).powf(thickness - 0.125);
        assert!(
            a <= thick + 1e-4 && a >= thin - 1e-4,
            "z {}: alpha {a} not in [{thin}, {thick}]",
            ray.origin.z
        );
    }
}

/// A deterministic, non-smooth test field.
fn field(x: u32, y: u32, z: u32) -> u8 {
    let h = x
        .wrapping_mul(73_856_093)
        .wrapping_add(y.wrapping_mul(19_349_663))
        .wrapping_add(z.wrapping_mul(83_492_791));
    (((h >> 7) % 200) as u8).saturating_add(if (x + y + z).is_multiple_of(5) { 55 } else { 0 })
}

#[test]
fn a_crop_box_renders_the_sub_volume_it_keeps() {
    // The crop box [8, 30] × [4, 18] × [6, 15] of a 40 × 24 × 20 volume, against a
    // 23 × 15 × 10 volume holding the same voxels, seen by the same rays moved by
    // the box's corner. Along +x at step 0.5 the full volume's samples from x = 0
    // fall on the sub-volume's from its x = 0 (8 is a whole number of steps), so
    // both take the same samples at the same places: the images are equal bit for
    // bit in every mode that needs no gradient (one-sided at the sub-volume's faces).
    let full = volume_u8([40, 24, 20], [1.0; 3], field);
    let sub = volume_u8([23, 15, 10], [1.0; 3], |x, y, z| field(x + 8, y + 4, z + 6));
    let corner = Vec3::new(8.0, 4.0, 6.0);
    let eye = Vec3::new(-10.0, 12.0, 10.0);
    let (full_camera, sub_camera) = (along_x(eye), along_x(eye - corner));
    let clip = ClipRegion {
        crop: crop([8.0, 4.0, 6.0], [30.0, 18.0, 15.0]),
        planes: Vec::new(),
    };
    let tf = white_tf(&[(0.0, 0.0), (0.3, 0.02), (0.7, 0.3), (1.0, 0.6)]);
    for mode in [
        Mode::Dvr,
        Mode::Mip,
        Mode::Average,
        Mode::XRay,
        Mode::FirstHit,
        Mode::Sabella,
    ] {
        for brick in [Some(8), None] {
            let settings = RenderSettings {
                mode,
                iso_value: 0.6,
                early_termination: Some(0.95),
                ..plain_settings(tf.clone())
            };
            let expected = render_bricked(&sub, brick, &sub_camera, &settings);
            let cropped_settings = RenderSettings {
                clip: clip.clone(),
                ..settings
            };
            let cropped = render_bricked(&full, brick, &full_camera, &cropped_settings);
            let name = format!("crop-{}-{brick:?}", mode.name());
            assert_eq!(cropped.rgba, expected.rgba, "{name}: pixels");
            assert_eq!(cropped.depth, expected.depth, "{name}: depths");
            assert_eq!(
                cropped.stats.counters.samples, expected.stats.counters.samples,
                "{name}: samples"
            );
            assert!(expected.rgba.iter().any(|p| p[3] > 0.0), "{name}: empty");
            // And the parallel renderer.
            let prepared = RenderVolume::new(&full, brick).unwrap();
            let options = ParallelOptions {
                render_threads: 2,
                compositing_threads: 1,
                tile_size: 8,
            };
            let parallel =
                render_parallel(&prepared, &full_camera, &cropped_settings, &options).unwrap();
            assert_eq!(parallel.rgba, expected.rgba, "{name}: parallel pixels");
        }
    }
}

#[test]
fn a_crop_box_of_the_whole_volume_changes_nothing() {
    let volume = volume_u8([30, 20, 25], [1.0, 1.5, 0.8], field);
    let camera = default_camera(&volume, 40);
    let tf = white_tf(&[(0.0, 0.0), (0.5, 0.1), (1.0, 0.5)]);
    for jitter in [false, true] {
        let settings = RenderSettings {
            jitter,
            ..plain_settings(tf.clone())
        };
        let whole = render(&volume, &camera, &settings);
        let cropped = render(
            &volume,
            &camera,
            &RenderSettings {
                clip: ClipRegion {
                    crop: crop([-1.0, -1.0, -1.0], [40.0, 40.0, 40.0]),
                    planes: vec![plane([-3.0, 0.0, 0.0], [1.0, 0.2, 0.0])],
                },
                ..settings
            },
        );
        assert_eq!(cropped.rgba, whole.rgba, "jitter {jitter}");
    }
}

#[test]
fn bricks_outside_the_region_are_left_out_and_a_region_outside_shows_nothing() {
    let volume = volume_u8([48, 48, 48], [1.0; 3], field);
    let camera = default_camera(&volume, 48);
    let tf = white_tf(&[(0.0, 0.02), (1.0, 0.3)]);
    let prepared = RenderVolume::new(&volume, Some(16)).unwrap();
    let options = ParallelOptions {
        render_threads: 2,
        compositing_threads: 1,
        tile_size: 16,
    };
    let settings = plain_settings(tf);
    let whole = render_parallel(&prepared, &camera, &settings, &options).unwrap();
    // One brick of the 64 (side 16, step 15: 4 per axis).
    let corner = RenderSettings {
        clip: ClipRegion {
            crop: crop([0.0; 3], [14.0; 3]),
            planes: Vec::new(),
        },
        ..settings.clone()
    };
    let cut = render_parallel(&prepared, &camera, &corner, &options).unwrap();
    let reference = render_sequential(&prepared, &camera, &corner).unwrap();
    assert_eq!(cut.rgba, reference.rgba);
    assert!(
        cut.stats.counters.tasks * 4 < whole.stats.counters.tasks,
        "tasks: {} cut, {} whole",
        cut.stats.counters.tasks,
        whole.stats.counters.tasks
    );
    // A plane keeping nothing of the volume: no ray, no sample, background.
    let nothing = RenderSettings {
        clip: ClipRegion {
            crop: None,
            planes: vec![plane([60.0, 0.0, 0.0], [1.0, 0.0, 0.0])],
        },
        ..settings
    };
    for frame in [
        render_parallel(&prepared, &camera, &nothing, &options).unwrap(),
        render_sequential(&prepared, &camera, &nothing).unwrap(),
    ] {
        assert_eq!(frame.stats.counters.rays, 0);
        assert_eq!(frame.stats.counters.samples, 0);
        assert!(frame.rgba.iter().all(|p| *p == [0.0; 4]));
    }
}

#[test]
fn bad_regions_are_refused() {
    let volume: Volume = volume_u8([8, 8, 8], [1.0; 3], |_, _, _| 1);
    let camera = default_camera(&volume, 8);
    let prepared = RenderVolume::new(&volume, None).unwrap();
    let settings = RenderSettings {
        clip: ClipRegion {
            crop: None,
            planes: vec![plane([1.0, 1.0, 1.0], [0.0, 0.0, 0.0])],
        },
        ..RenderSettings::default()
    };
    let e = render_sequential(&prepared, &camera, &settings).unwrap_err();
    assert!(e.to_string().contains("zero normal"), "{e}");
}

#[test]
fn an_objects_own_region_cuts_only_that_object() {
    use raycaster::render::{GlobalMode, LocalMode, Membership, ObjectStyle, SegmentScene};
    // Two value layers along x: 100 for x < 8, 200 from x = 8 (voxels), each its
    // own object with the same constant opacity; object 2 keeps only x ≥ 12.
    let volume = volume_u8(
        [17, 9, 9],
        [1.0; 3],
        |x, _, _| if x < 8 { 100 } else { 200 },
    );
    let camera = along_x(Vec3::new(-10.0, 4.0, 4.0));
    let alpha0 = 0.05;
    let tf = white_tf(&[(0.0, alpha0), (1.0, alpha0)]);
    let object = |id: u8, clip: ClipRegion| ObjectStyle {
        name: format!("layer {id}"),
        id,
        visible: true,
        transfer: tf.clone(),
        mode: LocalMode::Dvr,
        clip,
    };
    let cut = ClipRegion {
        crop: None,
        planes: vec![plane([12.0, 0.0, 0.0], [1.0, 0.0, 0.0])],
    };
    let scene = SegmentScene {
        membership: Membership::Layers(vec![[0.0, 140.0 / 255.0], [140.0 / 255.0, 1.0]]),
        objects: vec![object(1, ClipRegion::default()), object(2, cut)],
        global: GlobalMode::Dvr,
    };
    let settings = RenderSettings {
        segments: Some(scene.clone()),
        ..plain_settings(tf.clone())
    };
    let frame = render(&volume, &camera, &settings);
    // Samples at x = 0, 0.5, …, 15.5, each a full step: object 1 holds those
    // below 140 (the value crosses it at x = 7.4: x ≤ 7, 15 samples), object 2
    // those from x = 12 (8 samples); x = 7.5 … 11.5 belong to no object.
    let expected = 1.0 - (1.0f32 - alpha0).powf((15.0 + 8.0) * 0.5);
    for (x, y) in slab_pixels() {
        let a = frame.rgba[frame.index(x, y)][3];
        assert!(
            (a - expected).abs() < 1e-4,
            "alpha {a}, expected {expected}"
        );
    }
    // The parallel renderer agrees; the scene file keeps the regions.
    let prepared = RenderVolume::new(&volume, Some(4)).unwrap();
    let options = ParallelOptions {
        render_threads: 2,
        compositing_threads: 1,
        tile_size: 5,
    };
    let parallel = render_parallel(&prepared, &camera, &settings, &options).unwrap();
    let sequential = render_sequential(&prepared, &camera, &settings).unwrap();
    assert_eq!(parallel.rgba, sequential.rgba);
    let text = scene.to_toml();
    assert!(
        text.contains("clip = [[12.0, 0.0, 0.0, 1.0, 0.0, 0.0]]"),
        "{text}"
    );
    assert_eq!(
        SegmentScene::parse(&text, std::path::Path::new(".")).unwrap(),
        scene
    );
    let bad = text.replace("1.0, 0.0, 0.0]]", "0.0, 0.0, 0.0]]");
    let e = SegmentScene::parse(&bad, std::path::Path::new(".")).unwrap_err();
    assert!(e.to_string().contains("zero normal"), "{e}");
}
