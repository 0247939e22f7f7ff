//! `isotopo`: the command line. Argument parsing, progress and printing only; the work is in the
//! `isotopo` library. One file per command in `commands/`; the flags several commands share are
//! defined once, in `args.rs`.

mod args;
mod commands;
mod print;
mod progress;
mod signals;

use clap::{Parser, Subcommand};
use commands::{analyze, convert, genus, handles, info, mesh, simplify};
use std::process::ExitCode;

#[derive(Parser)]
#[command(name = "isotopo", version, about = "Find, measure and remove small topological handles of isosurfaces of 3D volumes", long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// How large the process may grow: bytes, K/M/G/T (powers of 1024) or a percentage of the
    /// machine's memory. Past it, a run stops with an error naming what did not fit (exit code
    /// 2) instead of being killed. Default: 3/4 of the machine's memory (or the container's).
    #[arg(long, global = true, value_name = "SIZE", value_parser = isotopo::memory::parse_size)]
    max_memory: Option<u64>,
}

#[derive(Subcommand)]
enum Command {
    /// Describe a volume: dims, type, geometry, value statistics and a suggested isovalue.
    Info(info::InfoArgs),
    /// Convert a volume to another format (chosen by the output extension).
    Convert(convert::ConvertArgs),
    /// Genus of every surface of the isosurface and the solid's Betti numbers (one streaming pass).
    Genus(genus::GenusArgs),
    /// Extract the isosurface as a mesh (.ply binary, .obj or .stl), in world millimetres.
    Mesh(mesh::MeshArgs),
    /// Locate every handle with a sweep (Reeb graph of contours and ribbons).
    Handles(handles::HandlesArgs),
    /// Locate every handle and measure it: Reeb loop, cross loop, size; statistics and plots.
    Analyze(analyze::AnalyzeArgs),
    /// Remove every handle smaller than --tau by writing thin walls into the volume.
    Simplify(simplify::SimplifyArgs),
}

/// glibc serves large allocations from `mmap` only until the first one is freed, then raises its
/// threshold (up to 32 MiB) and keeps freed blocks in the heap: the loop searches' arrays, grown
/// and dropped handle after handle, would then hold the peak resident set far above what is in
/// use. A fixed threshold keeps large blocks in `mmap`, so freeing them returns the memory.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn return_freed_memory() {
    extern "C" {
        fn mallopt(param: i32, value: i32) -> i32;
    }
    const M_MMAP_THRESHOLD: i32 = -3;
    // SAFETY: mallopt only changes allocator settings; called before any thread starts.
    unsafe {
        mallopt(M_MMAP_THRESHOLD, 256 << 10);
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn return_freed_memory() {}

/// Exit codes: 0 done; 2 bad input or options (the message says what to change); 3 a bug in
/// isotopo (an internal check failed, or a panic); 130 interrupted (nothing was written).
fn main() -> ExitCode {
    return_freed_memory();
    signals::quiet_on_closed_pipe();
    signals::catch_interrupts();
    signals::report_panics();
    let cli = Cli::parse();
    isotopo::memory::set_limit(cli.max_memory);
    let run = std::panic::catch_unwind(|| match cli.command {
        // How the tests see what a bug would do (there is no other way to make one on purpose).
        _ if std::env::var_os("ISOTOPO_PANIC_FOR_TESTS").is_some() => panic!("a deliberate panic"),
        Command::Info(a) => info::run(a),
        Command::Convert(a) => convert::run(a),
        Command::Genus(a) => genus::run(a),
        Command::Mesh(a) => mesh::run(a),
        Command::Handles(a) => handles::run(a),
        Command::Analyze(a) => analyze::run(a),
        Command::Simplify(a) => simplify::run(a),
    });
    match run {
        Ok(Ok(())) => ExitCode::SUCCESS,
        Ok(Err(isotopo::Error::Cancelled)) => {
            eprintln!("isotopo: interrupted; nothing was written");
            ExitCode::from(130)
        }
        Ok(Err(e)) => {
            eprintln!("isotopo: error: {e}");
            ExitCode::from(if e.is_user_error() { 2 } else { 3 })
        }
        // The panic hook has said what happened.
        Err(_) => ExitCode::from(3),
    }
}
