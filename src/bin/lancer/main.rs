//! The `lancer` command line: render, list devices, describe a scene.
//!
//! One module per command (or group of them); `args` holds the options and
//! helpers they share, `flags` maps the settings the library's messages
//! name to this command line's flags, and `progress` draws the progress
//! bars. The library prints nothing: every line on the terminal is
//! printed here.
#![deny(unsafe_code)]

mod args;
mod bench;
mod compare;
mod converge;
mod convert;
mod devices;
mod flags;
mod info;
mod merge;
mod progress;
mod render;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

use lancer::util::interrupt;

/// A wavefront path tracer on Vulkan compute.
#[derive(Parser)]
#[command(name = "lancer", version = lancer::VERSION, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene to a PNG (sRGB) or EXR (linear) file.
    Render(render::RenderArgs),
    /// List the Vulkan devices lancer can use.
    Devices,
    /// Print the features a scene calls for, the passes and kernels that
    /// will run, and the sizes of what goes on the device.
    Info(info::InfoArgs),
    /// Measure error against render time and samples per pixel, for one or
    /// more settings, against a reference: CSV, JSON, plots and a table.
    Converge(converge::ConvergeArgs),
    /// Compare an image with a reference: RMSE, relMSE, bias, FLIP, the
    /// per-pixel z-test; exit code 1 when a tolerance is exceeded.
    Compare(compare::CompareArgs),
    /// Merge the film files of a render split into sample ranges
    /// (`render --samples A..B --film-out`) into one image.
    Merge(merge::MergeArgs),
    /// Write a scene (e.g. Mitsuba 3 XML) as a lancer TOML scene, with its
    /// triangles in OBJ files beside it.
    Convert(convert::ConvertArgs),
    /// Run a fixed suite of scenes (Cornell, glass, a million triangles)
    /// with every schedule: samples/s, Mrays/s per pass, time to first
    /// dispatch, device memory; compare with an earlier run.
    Bench(bench::BenchArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    // Ctrl-C stops a render between waves; a second one stops at once
    let _ = ctrlc::set_handler(|| {
        if interrupt::request() {
            std::process::exit(EXIT_INTERRUPTED.into());
        }
    });
    // `compare` keeps exit code 1 for "worse than the tolerance" and fails
    // with 2, so that a CI job can tell a bad image from a broken check
    let (result, failure) = match cli.command {
        Command::Render(args) => (render::render(args), 1),
        Command::Devices => (devices::devices(), 1),
        Command::Info(args) => (info::info(args), 1),
        Command::Converge(args) => (converge::converge(args), 1),
        Command::Compare(args) => (compare::compare(args), 2),
        Command::Convert(args) => (convert::convert(args), 1),
        Command::Merge(args) => (merge::merge(args), 1),
        Command::Bench(args) => (bench::bench(args), 1),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) if err.is::<compare::Worse>() => ExitCode::from(1),
        Err(err) if err.is::<interrupt::Interrupted>() => {
            eprintln!("{}", flags::named(&err.to_string()));
            ExitCode::from(EXIT_INTERRUPTED)
        }
        Err(err) => {
            eprintln!("error: {}", flags::named(&format!("{err:#}")));
            ExitCode::from(failure)
        }
    }
}

/// Exit code after Ctrl-C, as a shell reports a process ended by SIGINT.
const EXIT_INTERRUPTED: u8 = 130;
