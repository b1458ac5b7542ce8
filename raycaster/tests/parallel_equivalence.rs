//! The object-parallel renderer against its oracle, the sequential renderer, over
//! the parameter matrix: brick sizes, tile sizes, thread counts, ERT/ESS, linear vs
//! bricked storage, mapped vs RAM, perspective vs orthographic, camera outside,
//! grazing and inside the volume. Equal images (≤ 1/255) and sample counts within
//! 1 % prove that the parallel schedule keeps early termination global.

mod render_support;

use raycaster::render::{
    Camera, ClipPlane, ClipRegion, CropBox, Mode, ParallelOptions, Projection, RenderSettings,
    RenderVolume, Renderer, SimdLevel, Vec3, render_parallel, render_sequential, simd_levels,
};
use raycaster::synth::SceneKind;
use raycaster::volume::{Access, Layout, SampleType, Volume};
use render_support::*;

const BRICKS: [u32; 5] = [8, 16, 32, 64, 12];
const TILES: [u32; 5] = [1, 7, 10, 16, 64];
const THREADS: [usize; 4] = [1, 2, 3, 8];
const N: u32 = 40;
const SIZE: u32 = 40;

#[derive(Clone, Copy, Debug)]
enum View {
    Outside,
    Orthographic,
    Grazing,
    Inside,
}

fn camera(view: View, volume: &Volume) -> Camera {
    let c = centre(volume);
    let persp = |vfov_deg| Projection::Perspective { vfov_deg };
    match view {
        View::Outside => default_camera(volume, SIZE),
        View::Orthographic => Camera::look_at(
            c + Vec3::new(50.0, -35.0, 30.0),
            c,
            Vec3::Z,
            Projection::Orthographic { height: 70.0 },
            SIZE,
            SIZE,
        )
        .unwrap(),
        // In the plane of the bottom face, looking along it.
        View::Grazing => Camera::look_at(
            Vec3::new(c.x + 3.0, -60.0, 0.0),
            Vec3::new(c.x, c.y, 0.0),
            Vec3::Z,
            persp(50.0),
            SIZE,
            SIZE,
        )
        .unwrap(),
        View::Inside => Camera::look_at(
            c + Vec3::new(1.5, -2.0, 0.7),
            c + Vec3::new(20.0, 8.0, -5.0),
            Vec3::Z,
            persp(90.0),
            SIZE,
            SIZE,
        )
        .unwrap(),
    }
}

/// A tiny deterministic generator for covering the matrix.
struct Picker(u64);

impl Picker {
    fn pick<T: Copy>(&mut self, items: &[T]) -> T {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        items[((self.0 >> 33) % items.len() as u64) as usize]
    }
}

/// Variant `i` of the cut regions the matrix renders with (0: none), in voxels
/// of the `N³` volume.
fn clip_region(i: usize) -> ClipRegion {
    let n = (N - 1) as f32;
    let crop = Some(CropBox {
        lo: Vec3::new(0.15, 0.3, 0.1) * n,
        hi: Vec3::new(0.8, 0.95, 0.7) * n,
    });
    let planes = vec![
        ClipPlane {
            point: Vec3::splat(0.5 * n),
            normal: Vec3::new(1.0, -0.4, 0.3),
        },
        ClipPlane {
            point: Vec3::new(0.2, 0.6, 0.45) * n,
            normal: Vec3::new(-0.2, -1.0, 0.1),
        },
    ];
    match i {
        0 => ClipRegion::default(),
        1 => ClipRegion {
            crop,
            planes: Vec::new(),
        },
        2 => ClipRegion { crop: None, planes },
        3 => ClipRegion {
            crop,
            planes: planes[..1].to_vec(),
        },
        _ => ClipRegion {
            crop: None,
            planes: planes[1..].to_vec(),
        },
    }
}

#[test]
fn parallel_equals_sequential_over_the_parameter_matrix() {
    let dir = tempfile::tempdir().unwrap();
    let kind = SceneKind::Shapes;
    let ram_linear = scene_volume(kind, N);
    let views = [
        View::Outside,
        View::Orthographic,
        View::Grazing,
        View::Inside,
    ];
    let mut picker = Picker(12345);
    let mut kept = Renderer::new();
    let mut combos = 0;
    // Every value of every parameter appears: the first rounds walk each list in
    // step, the rest are drawn at random.
    for round in 0..60usize {
        let pick_at = |items_len: usize| round % items_len;
        let (brick, tile, threads, view) = if round < 20 {
            (
                BRICKS[pick_at(BRICKS.len())],
                TILES[pick_at(TILES.len())],
                THREADS[pick_at(THREADS.len())],
                views[pick_at(views.len())],
            )
        } else {
            (
                picker.pick(&BRICKS),
                picker.pick(&TILES),
                picker.pick(&THREADS),
                picker.pick(&views),
            )
        };
        let ert = picker.pick(&[true, false]);
        let ess = picker.pick(&[true, false]);
        let bricked = picker.pick(&[true, false]);
        let access = picker.pick(&[Access::Mapped, Access::Ram]);
        let mode = if round % 7 == 3 {
            Mode::FirstHit
        } else if round % 7 == 5 {
            Mode::Mip
        } else if round % 7 == 1 {
            // The other modes in turn: average, xray, importance, context,
            // silhouette, sabella.
            [
                Mode::Average,
                Mode::XRay,
                Mode::Importance,
                Mode::ContextPreserving,
                Mode::Silhouette,
                Mode::Sabella,
            ][(round / 7) % 6]
        } else {
            Mode::Dvr
        };
        let file;
        let (volume, brick_side) = if bricked {
            let layout = Layout::Bricked { side: brick as u8 };
            file = scene_file(dir.path(), kind, N, layout, SampleType::U8, access);
            (&file, None)
        } else if access == Access::Mapped {
            file = scene_file(dir.path(), kind, N, Layout::Linear, SampleType::U8, access);
            (&file, Some(brick))
        } else {
            (&ram_linear, Some(brick))
        };
        // Every kernel this machine runs: scalar and each packet level.
        let levels = simd_levels();
        let simd = levels[round % levels.len()];
        // Pre-integration (DVR; other modes ignore it) and ray-start jitter in
        // turn, without disturbing the picks above.
        let preintegrated = round % 3 == 0;
        let jitter = round % 4 < 2;
        // Every other pre-integrated frame at a step coarser than the cells,
        // where skipping checks the cells between samples.
        let step = if round % 6 == 0 {
            5.5
        } else {
            RenderSettings::default().step
        };
        // A crop box, clipping planes, both or neither in turn.
        let clip = clip_region(round % 5);
        let settings = RenderSettings {
            mode,
            early_termination: ert.then_some(0.99),
            empty_space_skipping: ess,
            transfer: scene_preset(kind),
            simd: Some(simd),
            preintegrated,
            jitter,
            clip,
            step,
            ..RenderSettings::default()
        };
        let cam = camera(view, volume);
        let prepared = RenderVolume::new(volume, brick_side).unwrap();
        let reference = render_sequential(&prepared, &cam, &scalar(&settings)).unwrap();
        let options = ParallelOptions {
            render_threads: threads,
            compositing_threads: 1 + round % 2,
            tile_size: tile,
        };
        // Every other frame on workers kept across frames (whose thread counts
        // change between frames), the others on threads started for the frame.
        let parallel = if round % 2 == 0 {
            kept.render(&prepared, &cam, &settings, &options).unwrap()
        } else {
            render_parallel(&prepared, &cam, &settings, &options).unwrap()
        };
        let name = format!(
            "par-{round}-b{brick}-t{tile}-r{threads}-{view:?}-{}-ert{ert}-ess{ess}-bricked{bricked}-{access:?}-{simd}-pre{preintegrated}-step{step}-jitter{jitter}-clip{}",
            mode.name(),
            round % 5
        );
        assert_images_match(&name, &parallel.to_image(), &reference.to_image(), 1);
        let (s, p) = (
            reference.stats.counters.samples,
            parallel.stats.counters.samples,
        );
        assert!(
            p.abs_diff(s) as f64 <= 0.01 * s as f64,
            "{name}: parallel took {p} samples, sequential {s}"
        );
        if preintegrated || jitter {
            assert_eq!(p, s, "{name}: sample counts");
        }
        // The parallel frame counts transparent bricks in its schedule's pass,
        // the sequential one over the grid: the same bricks.
        assert_eq!(
            parallel.stats.bricks_transparent, reference.stats.bricks_transparent,
            "{name}: transparent bricks"
        );
        combos += 1;
    }
    assert_eq!(combos, 60);
}

#[test]
fn logical_sub_bricks_of_a_bricked_file_render_the_same() {
    let dir = tempfile::tempdir().unwrap();
    let kind = SceneKind::Shells;
    let file = scene_file(
        dir.path(),
        kind,
        N,
        Layout::Bricked { side: 16 },
        SampleType::U16,
        Access::Mapped,
    );
    let cam = camera(View::Outside, &file);
    let settings = RenderSettings {
        transfer: scene_preset(kind),
        ..RenderSettings::default()
    };
    let whole = RenderVolume::new(&file, None).unwrap();
    let reference = render_sequential(&whole, &cam, &scalar(&settings))
        .unwrap()
        .to_image();
    for side in [4, 6, 16] {
        let sub = RenderVolume::new(&file, Some(side)).unwrap();
        let options = ParallelOptions {
            render_threads: 2,
            compositing_threads: 1,
            tile_size: 8,
        };
        let frame = render_parallel(&sub, &cam, &settings, &options).unwrap();
        assert_images_match(
            &format!("sub-brick-{side}"),
            &frame.to_image(),
            &reference,
            0,
        );
    }
    assert!(
        RenderVolume::new(&file, Some(5)).is_err(),
        "step 4 does not divide 15"
    );
}

/// A camera inside the volume exactly on brick faces (one plane, an edge, a
/// corner): the rays that leave it take their first sample in the brick that
/// owns the plane and the next in the brick on their side, which the parallel
/// schedule once put first when the two tied in distance (samples lost, sums
/// off by up to 16/255). The same images and the same samples as the
/// sequential renderer.
#[test]
fn a_camera_on_brick_faces_inside_the_volume_renders_as_the_sequential_renderer() {
    let kind = SceneKind::Shapes;
    let volume = scene_volume(kind, N);
    // Bricks of side 16 own 15 voxels each: faces at 15 and 30.
    let prepared = RenderVolume::new(&volume, Some(16)).unwrap();
    let mut checked = 0;
    for (eye, target) in [
        (Vec3::new(20.0, 30.0, 20.0), centre(&volume)),
        (Vec3::new(20.0, 30.0, 20.0), Vec3::new(20.0, 0.0, 22.0)),
        (Vec3::new(15.0, 30.0, 25.0), Vec3::new(35.0, 5.0, 10.0)),
        (Vec3::new(15.0, 15.0, 15.0), Vec3::new(30.0, 35.0, 2.0)),
        (Vec3::new(30.0, 22.0, 30.0), Vec3::new(0.0, 22.0, 0.0)),
    ] {
        let cam = Camera::look_at(
            eye,
            target,
            Vec3::Z,
            Projection::Perspective { vfov_deg: 100.0 },
            SIZE,
            SIZE,
        )
        .unwrap();
        for mode in [Mode::XRay, Mode::Average, Mode::Dvr] {
            let settings = RenderSettings {
                mode,
                transfer: scene_preset(kind),
                ..RenderSettings::default()
            };
            let reference = render_sequential(&prepared, &cam, &scalar(&settings)).unwrap();
            let options = ParallelOptions {
                render_threads: 2,
                compositing_threads: 1,
                tile_size: 8,
            };
            let frame = render_parallel(&prepared, &cam, &settings, &options).unwrap();
            let name = format!("eye {eye} to {target} {}", mode.name());
            assert_images_match(&name, &frame.to_image(), &reference.to_image(), 1);
            assert_eq!(
                frame.stats.counters.samples, reference.stats.counters.samples,
                "{name}"
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 15);
}

/// `settings` on the scalar kernel: the sequential renderer as the oracle.
fn scalar(settings: &RenderSettings) -> RenderSettings {
    RenderSettings {
        simd: Some(SimdLevel::Scalar),
        ..settings.clone()
    }
}
