//! `raycaster render --distributed`: one rank of an MPI job.
//!
//! Every rank opens the same file and renders its part of the volume
//! ([`raycaster::render::render_distributed`]); MPI carries the pixel states
//! between ranks. Each step that can fail is agreed on by all ranks: when any
//! rank fails, the lowest failing rank says why (once) and every rank exits,
//! none waits for a message that will not come.

use anyhow::Result;

use crate::render::RenderArgs;

/// Runs the render command as one rank of an MPI job.
#[cfg(feature = "mpi")]
pub fn run(args: RenderArgs) -> Result<()> {
    mpi_rank::run(args)
}

/// Without MPI compiled in, `--distributed` says how to get it.
#[cfg(not(feature = "mpi"))]
pub fn run(_args: RenderArgs) -> Result<()> {
    anyhow::bail!(
        "--distributed needs MPI, and this raycaster was built without it: build it with `cargo build --release -p raycaster-cli --features mpi` (needs libopenmpi-dev and libclang-dev; docs/distributed.md) and run it under mpirun"
    )
}

#[cfg(feature = "mpi")]
mod mpi_rank {
    use std::cell::RefCell;
    use std::sync::mpsc::RecvTimeoutError;
    use std::time::Duration;

    use anyhow::{Result, anyhow};
    use mpi::collective::SystemOperation;
    use mpi::request::{Request, StaticScope};
    use mpi::topology::SimpleCommunicator;
    use mpi::traits::*;
    use raycaster::render::{
        Compositing, DepthBand, DistributedOptions, Link, LinkError, RankStats, RenderError,
        RenderVolume, Renderer, render_distributed_levels,
    };

    use crate::output::check_output_of;
    use crate::render::{RenderArgs, Setup, finish, parallel_options};

    /// An error already reported (by this rank or another): exit quietly with
    /// failure.
    #[derive(Debug)]
    pub struct ReportedElsewhere;

    impl std::fmt::Display for ReportedElsewhere {
        fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
            f.write_str("another rank failed")
        }
    }

    impl std::error::Error for ReportedElsewhere {}

    /// MPI point-to-point messages as the renderer's [`Link`].
    ///
    /// Sends are immediate (`MPI_Isend`): a rank goes on with its next band
    /// while the rank behind it is still busy, instead of waiting until that
    /// rank posts the matching receive. A send's buffer must stay put until
    /// the send completes, so it is kept for the rest of the process (one
    /// frame per process: at most what the rank sends in that frame).
    struct MpiLink<'w> {
        world: &'w SimpleCommunicator,
        pending: RefCell<Vec<Request<'static, [u8], StaticScope>>>,
    }

    impl Link for MpiLink<'_> {
        fn rank(&self) -> usize {
            self.world.rank() as usize
        }

        fn ranks(&self) -> usize {
            self.world.size() as usize
        }

        fn send(&self, to: usize, tag: u32, message: Vec<u8>) -> Result<(), LinkError> {
            if message.len() > i32::MAX as usize {
                return Err(LinkError(format!(
                    "a message of {} bytes is over MPI's 2 GiB count limit: use a smaller image or more --bands",
                    message.len()
                )));
            }
            let buffer: &'static [u8] = Box::leak(message.into_boxed_slice());
            let request = self
                .world
                .process_at_rank(to as i32)
                .immediate_send_with_tag(StaticScope, buffer, tag as i32);
            self.pending.borrow_mut().push(request);
            Ok(())
        }

        fn flush(&self) -> Result<(), LinkError> {
            for request in self.pending.borrow_mut().drain(..) {
                request.wait();
            }
            Ok(())
        }

        fn receive(&self, from: usize, tag: u32) -> Result<Vec<u8>, LinkError> {
            let (message, _status) = self
                .world
                .process_at_rank(from as i32)
                .receive_vec_with_tag::<u8>(tag as i32);
            Ok(message)
        }
    }

    /// Whether every rank got `result`: `Ok` everywhere, or else
    /// [`ReportedElsewhere`] everywhere once the lowest failing rank has said why.
    ///
    /// The error is printed here, before a barrier that every rank passes
    /// before it returns: a rank that exits with failure makes `mpirun` end the
    /// job, and a rank still on its way to printing would be ended silently.
    fn agree<T>(world: &SimpleCommunicator, result: Result<T>) -> Result<T> {
        let rank = world.rank();
        let mine = if result.is_err() { rank } else { i32::MAX };
        let mut first = i32::MAX;
        world.all_reduce_into(&mine, &mut first, SystemOperation::min());
        if first == i32::MAX {
            return result;
        }
        if let Err(e) = result
            && first == rank
        {
            let e = if world.size() > 1 {
                e.context(format!("rank {rank} of {}", world.size()))
            } else {
                e
            };
            crate::report_error(&e);
        }
        crate::ERROR_SAID.store(true, std::sync::atomic::Ordering::Relaxed);
        world.barrier();
        Err(ReportedElsewhere.into())
    }

    /// Whether this rank set up the frame rank 0 did, part by part: the
    /// volume (size, sample type, spacing, levels; its samples, by their
    /// brick value ranges), the label volume, the image size and camera, and
    /// each setting. Ranks that read another file (a path that differs
    /// between machines) or were given other flags would exchange pixel
    /// states of other frames: they hung waiting for bands that never came,
    /// or wrote a mixed image. The first part that differs is named.
    fn same_frame_as_rank_0(
        world: &SimpleCommunicator,
        setup: &Setup,
        args: &RenderArgs,
    ) -> Result<()> {
        use std::hash::{DefaultHasher, Hash, Hasher};
        let volume = &setup.volume;
        let shape = |v: &raycaster::volume::Volume| {
            let [x, y, z] = v.dims();
            let [sx, sy, sz] = v.spacing().map(raycaster::volume::number_text);
            format!(
                "{x}x{y}x{z} {}, spacing {sx} x {sy} x {sz}, {}",
                v.sample_type(),
                raycaster::text::counted(v.level_count() as u64, "level")
            )
        };
        // Brick value ranges, and the voxels of an 8×8×8 lattice (ranges alone
        // miss label volumes whose bricks each hold the same ids).
        let samples = |v: &raycaster::volume::Volume| {
            let d = v.dims();
            let lattice: Vec<u16> = (0..512u32)
                .map(|i| {
                    let at = |k: u32, n: u32| ((2 * k + 1) * n / 16).min(n - 1);
                    v.voxel([at(i % 8, d[0]), at(i / 8 % 8, d[1]), at(i / 64, d[2])])
                })
                .collect();
            format!("{:?} {lattice:?}", v.ranges().as_slice())
        };
        let labels = setup.labels.as_ref();
        let settings = &setup.settings;
        let camera = &setup.camera;
        let size = format!("{}x{}", camera.width(), camera.height());
        let step = settings.step.to_string();
        // (Part, what this rank says of it, what is compared; a file's path
        // may differ between machines, so it is said, never compared.)
        let parts: Vec<(&str, String, String)> = vec![
            (
                "volume",
                format!("{} is {}", volume.path().display(), shape(volume)),
                shape(volume),
            ),
            (
                "volume's samples",
                volume.path().display().to_string(),
                samples(volume),
            ),
            (
                "label volume",
                labels.map_or("none".into(), |l| l.path().display().to_string()),
                labels.map_or("none".into(), |l| format!("{:?} {}", l.dims(), samples(l))),
            ),
            ("image size", size.clone(), size),
            ("camera", String::new(), format!("{camera:?}")),
            (
                "mode",
                format!("{:?}", settings.mode),
                format!(
                    "{:?} {:?} {}",
                    settings.mode, settings.mode_parameters, settings.iso_value
                ),
            ),
            ("step", step.clone(), step),
            (
                "transfer function",
                String::new(),
                format!("{:?}", settings.transfer),
            ),
            (
                "scene (--segments)",
                String::new(),
                format!("{:?}", settings.segments),
            ),
            (
                "early termination, empty-space skipping, shading",
                String::new(),
                format!(
                    "{:?} {} {:?}",
                    settings.early_termination, settings.empty_space_skipping, settings.shading
                ),
            ),
            (
                "background, pre-integration, jitter",
                String::new(),
                format!(
                    "{:?} {} {}",
                    settings.background, settings.preintegrated, settings.jitter
                ),
            ),
            (
                "crop and clipping planes",
                String::new(),
                format!("{:?}", settings.clip),
            ),
            ("levels", String::new(), format!("{:?}", setup.bands)),
            (
                "--bands and --compositing",
                String::new(),
                format!("{:?} {:?}", args.bands, args.compositing),
            ),
        ];
        // (DefaultHasher::new has fixed keys: every rank runs this binary.)
        let mine: Vec<u64> = parts
            .iter()
            .map(|(_, _, compared)| {
                let mut h = DefaultHasher::new();
                compared.hash(&mut h);
                h.finish()
            })
            .collect();
        let mut all = vec![0u64; mine.len() * world.size() as usize];
        world.all_gather_into(&mine[..], &mut all[..]);
        let rank_0 = &all[..mine.len()];
        let Some(((part, said, _), _)) = parts
            .iter()
            .zip(mine.iter().zip(rank_0))
            .find(|(_, (m, r))| m != r)
        else {
            return Ok(());
        };
        let here = if said.is_empty() {
            String::new()
        } else {
            format!(" ({said})")
        };
        let what = match *part {
            "volume" | "volume's samples" | "label volume" => {
                "every rank must read the same files (on a cluster, the same file at the same path)"
            }
            _ => "every rank must be given the same flags",
        };
        Err(anyhow!("its {part}{here} is not rank 0's: {what}"))
    }

    /// A panic on one rank aborts the whole job instead of leaving the others
    /// waiting for its messages.
    fn abort_job_on_panic() {
        let default = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            default(info);
            SimpleCommunicator::world().abort(70);
        }));
    }

    /// How long a rank waits for the job's other processes to join before it
    /// says what may be wrong.
    const JOIN_WAIT: Duration = Duration::from_secs(30);

    /// Says, once, if the job has not come together within [`JOIN_WAIT`]
    /// (MPI waits for every process of the job: one started without
    /// `--distributed`, in a job of several command lines, never joins and
    /// the others waited silently); a message on the returned sender (or its
    /// drop) says it has.
    fn warn_unless_joined() -> std::sync::mpsc::Sender<()> {
        let (joined, watch) = std::sync::mpsc::channel::<()>();
        if !first_of_its_command_line() {
            return joined;
        }
        // (Without a thread for it, no warning: the job runs as it would.)
        let _ = std::thread::Builder::new()
            .name("mpi-join-watch".into())
            .spawn(move || {
                if watch.recv_timeout(JOIN_WAIT) != Err(RecvTimeoutError::Timeout) {
                    return;
                }
                eprintln!(
                    "warning: the MPI job has not come together after {} s: every process of it must run `raycaster render --distributed` with the same flags (one started without it never joins; docs/distributed.md)",
                    JOIN_WAIT.as_secs()
                );
            });
        joined
    }

    /// Whether this process is the first rank of its command line in the job
    /// (`mpirun -np 1 A : -np 2 B` has two), from what Open MPI sets before
    /// MPI starts: the waiting ranks of one command line say their warning
    /// once. Without those variables (another launcher), every rank is.
    fn first_of_its_command_line() -> bool {
        let var = |name: &str| std::env::var(name).ok();
        let (Some(rank), Some(app), Some(sizes)) = (
            var("OMPI_COMM_WORLD_RANK").and_then(|r| r.trim().parse::<u64>().ok()),
            var("OMPI_MCA_orte_app_num").and_then(|a| a.trim().parse::<usize>().ok()),
            var("OMPI_APP_CTX_NUM_PROCS"),
        ) else {
            return true;
        };
        let sizes: Option<Vec<u64>> = sizes.split_whitespace().map(|n| n.parse().ok()).collect();
        sizes.is_none_or(|sizes| sizes.iter().take(app).sum::<u64>() == rank)
    }

    pub fn run(mut args: RenderArgs) -> Result<()> {
        let joined = warn_unless_joined();
        let (universe, _threading) = mpi::initialize_with_threading(mpi::Threading::Funneled)
            .ok_or_else(|| anyhow!("MPI could not be initialised"))?;
        abort_job_on_panic();
        let world = universe.world();
        let rank = world.rank();
        // Every rank sets up the same frame: its warnings are said once, by
        // rank 0 (errors are agreed on and said by the failing rank).
        if rank > 0 {
            args.quiet = true;
        }
        // Ranks sharing this machine share its cores.
        let local = world.split_shared(rank).size().max(1) as usize;
        let checked = if rank == 0 {
            check_output_of(&args.output, args.force, crate::render::input_paths(&args))
        } else {
            Ok(())
        };
        agree(&world, checked)?;
        // (Every rank reached the first collective step: the job is whole.)
        let _ = joined.send(());
        let mut setup = agree(&world, Setup::new(&args))?;
        agree(&world, same_frame_as_rank_0(&world, &setup, &args))?;
        if Compositing::from(args.compositing) == Compositing::DirectSend {
            let bands_given = match args.bands {
                Some(_) => Err(anyhow!(
                    "--bands pipelines the relay; --compositing direct-send has no bands"
                )),
                None => Ok(()),
            };
            agree(&world, bands_given)?;
            // Partial images of one level: the nearest band's for the whole frame.
            // (Not for a frame direct send refuses: its error follows.)
            if let [nearest, .., farthest] = &setup.bands[..]
                && !args.quiet
                && setup.settings.direct_send_composites()
            {
                eprintln!(
                    "warning: direct-send renders one level for the whole frame, level {}; one process (and the relay) samples the farther depths at levels up to {}: the pictures differ (--level {} renders that level alike in each)",
                    nearest.level, farthest.level, nearest.level
                );
            }
            setup.bands.truncate(1);
            setup.bands[0].depth = None;
        }
        let prepared = agree(&world, setup.prepared_bands(&args))?;
        let passes: Vec<(&RenderVolume<'_>, Option<DepthBand>)> = prepared
            .iter()
            .zip(&setup.bands)
            .map(|(volume, band)| (volume, band.depth))
            .collect();
        let options = DistributedOptions {
            parallel: parallel_options(&args, local),
            bands: args.bands,
            compositing: args.compositing.into(),
        };
        let link = MpiLink {
            world: &world,
            pending: RefCell::new(Vec::new()),
        };
        let result = render_distributed_levels(
            &link,
            &mut Renderer::new(),
            &passes,
            &setup.camera,
            &setup.settings,
            &options,
        );
        // Setup errors come before any message and alike on every rank; a
        // failure between ranks may leave others waiting for this one: end
        // the job.
        if let Err(e @ RenderError::Distributed(_)) = &result {
            eprintln!("error: {e}");
            world.abort(1);
        }
        let result = agree(&world, result.map_err(anyhow::Error::from))?;
        let Some(frame) = result.frame else {
            return Ok(());
        };
        if args.stats {
            eprint!("{}", rank_table(&result.ranks, result.gather));
        }
        let mut extra = serde_json::Map::new();
        if args.stats_json {
            extra.insert("ranks".into(), rank_json(&result.ranks));
            extra.insert("gather_seconds".into(), result.gather.as_secs_f64().into());
        }
        let image = frame.to_image();
        crate::render::warn_of_dark_average(&args, &setup, &image)?;
        finish(&args, &setup, &frame, &image, extra)
    }

    /// Per-rank statistics for `--stats-json`.
    fn rank_json(ranks: &[RankStats]) -> serde_json::Value {
        ranks
            .iter()
            .map(|r| {
                let part = r.part_box();
                serde_json::json!({
                    "rank": r.rank,
                    "part_lo": part.lo,
                    "part_hi": part.hi,
                    "rendered_bricks": r.bricks,
                    "samples": r.counters.samples,
                    "bands": r.bands,
                    "render_seconds": r.render.as_secs_f64(),
                    "relay_seconds": r.relay.as_secs_f64(),
                })
            })
            .collect()
    }

    /// Per-rank statistics as an aligned table.
    fn rank_table(ranks: &[RankStats], gather: Duration) -> String {
        let mut out = String::from(
            "rank  part (bricks lo..hi)            rendered bricks   samples      bands  render s  relay s\n",
        );
        for r in ranks {
            let part = r.part_box();
            out += &format!(
                "{:>4}  {:<30}  {:>15}  {:>11}  {:>5}  {:>8.3}  {:>7.3}\n",
                r.rank,
                format!("{:?}..{:?}", part.lo, part.hi),
                r.bricks,
                r.counters.samples,
                r.bands,
                r.render.as_secs_f64(),
                r.relay.as_secs_f64(),
            );
        }
        out += &format!(
            "gather           {:.3} s (rank 0 receiving and assembling the bands)\n",
            gather.as_secs_f64()
        );
        out
    }
}

/// Whether `e` was already reported by another rank (exit quietly).
pub fn reported_elsewhere(e: &anyhow::Error) -> bool {
    #[cfg(feature = "mpi")]
    {
        e.is::<mpi_rank::ReportedElsewhere>()
    }
    #[cfg(not(feature = "mpi"))]
    {
        let _ = e;
        false
    }
}
