//! raycaster: render volume files headlessly.
//!
//! A thin command-line shell around the `raycaster` library; every camera,
//! transfer function and renderer lives there.

// `println!` and its kin without the standard library's panic when the stream
// cannot take the text (a full disk, a closed standard output): the
// `raycaster::console` functions; defined before the modules, they stand in
// for the standard macros in all of them.
macro_rules! println {
    () => { raycaster::console::print_line(format_args!("")) };
    ($($arg:tt)*) => { raycaster::console::print_line(format_args!($($arg)*)) };
}
#[allow(unused_macros)] // (every one stands in, used or not yet)
macro_rules! print {
    ($($arg:tt)*) => { raycaster::console::print(format_args!($($arg)*)) };
}
macro_rules! eprintln {
    () => { raycaster::console::eprint_line(format_args!("")) };
    ($($arg:tt)*) => { raycaster::console::eprint_line(format_args!($($arg)*)) };
}
#[allow(unused_macros)]
macro_rules! eprint {
    ($($arg:tt)*) => { raycaster::console::eprint(format_args!($($arg)*)) };
}

mod args;
mod bench;
mod compare;
mod distributed;
mod memory;
mod output;
mod plot;
mod render;
mod slice;
mod stats;
mod threads;

use clap::{Parser, Subcommand};

/// CPU ray casting of huge bricked, memory-mapped volumes.
///
/// Exit status: 0 done, 1 failed (the error says why, in one line), 2 the
/// command line is wrong (an unknown flag, or a value a flag does not take),
/// 130 interrupted (Ctrl-C, SIGTERM, SIGHUP: no partial output is left).
#[derive(Parser, Debug)]
#[command(name = "raycaster", version, propagate_version = true)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    Render(Box<render::RenderArgs>),
    Bench(Box<bench::BenchArgs>),
    Compare(compare::CompareArgs),
    Slice(slice::SliceArgs),
}

fn main() {
    restore_sigpipe();
    stop_cleanly_on_signals();
    raycaster::files::guard_mapped_reads("stopped, nothing was written");
    raycaster::files::fail_writes_past_the_file_size_limit();
    use clap::{CommandFactory, FromArgMatches};
    // Started by mpirun itself with one command line for every rank: what is
    // wrong with it is said once, by rank 0. (Ranks given other command
    // lines, `mpirun -np 1 A : -np 1 B`, or started by a script each rank
    // runs, say their own.)
    let launched = launched_as_rank();
    let one_command_line = launched.is_some_and(|(_, size)| size > 1)
        && std::env::var("OMPI_NUM_APP_CTX").map_or(true, |n| n == "1")
        && started_by_mpirun();
    let other_rank = one_command_line && launched.is_some_and(|(rank, _)| rank > 0);
    let exit = |e: clap::Error| -> ! {
        if other_rank {
            std::process::exit(e.exit_code());
        }
        e.exit()
    };
    let matches = Cli::command().try_get_matches().unwrap_or_else(|e| exit(e));
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| exit(e));
    if let Command::Render(args) = &cli.command
        && let Some(given) = matches.subcommand_matches("render")
        && let Some(conflict) = args.conflict(given)
    {
        let mut cli = Cli::command();
        cli.build();
        let render = cli.find_subcommand_mut("render").expect("a render command");
        exit(render.error(clap::error::ErrorKind::ArgumentConflict, conflict));
    }
    if let Command::Render(args) = &cli.command
        && !args.distributed
        && one_command_line
        && let Some((_, size)) = launched
    {
        // (A warning, not a refusal: a launcher in between can hide a
        // command line of each rank's own.)
        if !other_rank && !args.quiet {
            eprintln!(
                "warning: raycaster render runs as {size} processes under mpirun, each rendering the whole frame: --distributed renders one frame together (docs/distributed.md)"
            );
        }
    }
    let result = match cli.command {
        Command::Render(a) => render::run(*a),
        Command::Bench(a) => bench::run(*a),
        Command::Compare(a) => compare::run(a),
        Command::Slice(a) => slice::run(a),
    };
    if let Err(e) = result {
        if distributed::reported_elsewhere(&e) {
            std::process::exit(1);
        }
        // (The ranks of a distributed frame agree on errors and name the
        // failing rank; any other error is every rank's, said once.)
        if !other_rank {
            report_error(&e);
        }
        std::process::exit(1);
    }
    // The work is done and its files written; what it printed was not.
    if let Some(failure) = raycaster::console::stdout_failure() {
        eprintln!("error: {failure}");
        std::process::exit(1);
    }
}

/// This process's rank and the job's size when mpirun started it (Open MPI's
/// variables, or the PMI ones of MPICH and others); `None` outside MPI.
fn launched_as_rank() -> Option<(u32, u32)> {
    let number = |names: [&str; 2]| {
        names
            .iter()
            .find_map(|n| std::env::var(n).ok()?.parse::<u32>().ok())
    };
    Some((
        number(["OMPI_COMM_WORLD_RANK", "PMI_RANK"])?,
        number(["OMPI_COMM_WORLD_SIZE", "PMI_SIZE"])?,
    ))
}

/// Whether this process's parent is an MPI launcher (mpirun, or its daemon
/// on another node): the command line is the one mpirun was given, not one a
/// script built for this rank.
fn started_by_mpirun() -> bool {
    let parent = std::os::unix::process::parent_id();
    std::fs::read_to_string(format!("/proc/{parent}/comm")).is_ok_and(|name| {
        matches!(
            name.trim(),
            "mpirun" | "mpiexec" | "orterun" | "orted" | "prterun" | "prted" | "hydra_pmi_proxy"
        )
    })
}

/// Prints `e` the one way the command reports a failure (`error: …`).
pub(crate) fn report_error(e: &anyhow::Error) {
    eprintln!("error: {}", raycaster::errors::error_text(e.as_ref()));
    ERROR_SAID.store(true, std::sync::atomic::Ordering::Relaxed);
}

/// An error was said (by this process, or by another rank of the job): a
/// signal that follows (mpirun ending the other ranks) ends the process
/// without a second line.
pub(crate) static ERROR_SAID: std::sync::atomic::AtomicBool =
    std::sync::atomic::AtomicBool::new(false);

/// Ctrl-C, SIGTERM and SIGHUP end the process with status 130, as a shell
/// reports an interrupted command, after deleting the temporary files of
/// outputs still being written: a bench volume being generated into the cache
/// folder (gigabytes) or an image being saved. Killed by the signal itself,
/// the process left them behind.
fn stop_cleanly_on_signals() {
    // (Only fails when a handler is already set: none is.)
    let _ = ctrlc::set_handler(|| {
        raycaster::files::remove_partial_outputs();
        // Not glued to the end of a progress line.
        if render::PROGRESS_LINE_OPEN.load(std::sync::atomic::Ordering::Relaxed) {
            if std::io::IsTerminal::is_terminal(&std::io::stderr()) {
                eprint!("\r{:70}\r", "");
            } else {
                eprintln!();
            }
        }
        // Under mpirun only rank 0 says it (mpirun signals every rank), and
        // no rank after an error was said.
        let other_rank = launched_as_rank().is_some_and(|(rank, _)| rank > 0);
        if ERROR_SAID.load(std::sync::atomic::Ordering::Relaxed) {
            std::process::exit(1);
        }
        if !other_rank {
            eprintln!("interrupted; no partial output was left");
        }
        std::process::exit(130);
    });
}

/// A closed stdout (`raycaster render --stats-json | head -c 10`) ends the process
/// quietly, as for any Unix tool, instead of a panic in `println!` (Rust ignores
/// SIGPIPE).
/// A closed standard output no longer ends the process (a command whose
/// files are written after its table): writes to it fail instead, and
/// `raycaster::console` skips the rest.
#[allow(unsafe_code)] // signal() has no safe wrapper in std
pub(crate) fn ignore_sigpipe() {
    // SAFETY: setting a signal's disposition; no handler runs Rust code.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_IGN);
    }
}

#[allow(unsafe_code)] // signal() has no safe wrapper in std
fn restore_sigpipe() {
    // SAFETY: setting a signal's disposition to the default before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}
