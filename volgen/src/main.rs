//! volgen: generate, convert and inspect `.vol` volume files.
//!
//! A thin command-line shell around the `raycaster` library: every format, scene and
//! conversion lives there.

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
mod convert;
mod generate;
mod info;
mod output;
mod progress;
mod pyramid;

use clap::{Parser, Subcommand};

/// Generate, convert and inspect .vol volume files (the raycaster format).
///
/// Outputs are written to a temporary file beside the target and renamed when
/// complete: a failed or interrupted run (Ctrl-C) leaves no partial file, and an
/// existing file is only replaced with --force. Exit status: 0 done, 1 failed,
/// 2 the command line is wrong (an unknown flag, or a value a flag does not
/// take), 130 interrupted (Ctrl-C, SIGTERM, SIGHUP).
#[derive(Parser, Debug)]
#[command(
    name = "volgen",
    version,
    propagate_version = true,
    allow_negative_numbers = true
)]
struct Cli {
    /// Worker threads (default: one per core; at most 1024).
    #[arg(long, global = true, value_parser = clap::value_parser!(u16).range(1..=1024), value_name = "N")]
    threads: Option<u16>,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    Generate(generate::GenerateArgs),
    Convert(convert::ConvertArgs),
    Info(info::InfoArgs),
    Pyramid(pyramid::PyramidArgs),
}

fn main() {
    restore_sigpipe();
    raycaster::files::guard_mapped_reads("stopped, nothing was written");
    raycaster::files::fail_writes_past_the_file_size_limit();
    let cli = Cli::parse();
    // Started now (one per core unless --threads), so that a system refusing
    // threads (an address-space or process limit) is said here, once; rayon's
    // pool, started at its first use, panicked.
    let pool = rayon::ThreadPoolBuilder::new().num_threads(cli.threads.map_or(0, usize::from));
    if let Err(e) = pool.build_global() {
        eprintln!(
            "error: cannot start the worker threads: {e}; raise the limit (ulimit -v, ulimit -u) or give fewer with --threads"
        );
        std::process::exit(1);
    }
    progress::install_signal_handler();
    let result = match cli.command {
        Command::Generate(a) => generate::run(a),
        Command::Convert(a) => convert::run(a),
        Command::Info(a) => info::run(a),
        Command::Pyramid(a) => pyramid::run(a),
    };
    if let Err(e) = result {
        // Stopped by a signal: 130, as a shell reports an interrupted command,
        // so that scripts tell an interruption from a failure; said as
        // `raycaster` says it (the job's own error is only its cancellation).
        if progress::CANCEL.load(std::sync::atomic::Ordering::Relaxed) {
            eprintln!("interrupted; no partial output was left");
            std::process::exit(130);
        }
        eprintln!("error: {}", raycaster::errors::error_text(e.as_ref()));
        let wrong_command_line = e.downcast_ref::<args::CommandLineError>().is_some();
        std::process::exit(if wrong_command_line { 2 } else { 1 });
    }
    // The work is done and its files written; what it printed was not.
    if let Some(failure) = raycaster::console::stdout_failure() {
        eprintln!("error: {failure}");
        std::process::exit(1);
    }
}

/// A closed stdout (`volgen info big.vol | head -3`) ends the process quietly, as
/// for any Unix tool, instead of a panic in `println!` (Rust ignores SIGPIPE).
#[allow(unsafe_code)] // signal() has no safe wrapper in std
fn restore_sigpipe() {
    // SAFETY: setting a signal's disposition to the default before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}
