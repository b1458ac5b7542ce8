//! raycaster: render volume files headlessly.
//!
//! A thin command-line shell around the `raycaster` library; every camera,
//! transfer function and renderer lives there.

mod args;
mod bench;
mod compare;
mod distributed;
mod output;
mod plot;
mod render;
mod slice;
mod stats;

use clap::{Parser, Subcommand};

/// CPU ray casting of huge bricked, memory-mapped volumes.
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
    raycaster::files::guard_mapped_reads();
    let cli = Cli::parse();
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
        report_error(&e);
        std::process::exit(1);
    }
}

/// Prints `e` the one way the command reports a failure (`error: …`).
pub(crate) fn report_error(e: &anyhow::Error) {
    eprintln!("error: {}", raycaster::errors::error_text(e.as_ref()));
}

/// A closed stdout (`raycaster render --stats-json | head -c 10`) ends the process
/// quietly, as for any Unix tool, instead of a panic in `println!` (Rust ignores
/// SIGPIPE).
#[allow(unsafe_code)] // signal() has no safe wrapper in std
fn restore_sigpipe() {
    // SAFETY: setting a signal's disposition to the default before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}
