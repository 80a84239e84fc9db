//! `psns`: the command-line front-end of the psns emulator. This file only dispatches: each
//! command's options and body live in `src/cli/<command>.rs`; the emulator itself is the `psns`
//! library.

mod cli;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};
use std::process::ExitCode;

#[derive(Parser)]
#[command(
    name = "psns",
    version,
    about = "Polarized skylight + IMX250MZR polarization camera emulator"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand)]
enum Cmd {
    /// Render a scene: ideal LI/DOP/AOP images, polarizer images and visualisations.
    Render(psns::options::RenderArgs),
    /// Sky values for directions read as CSV on stdin (header `zenith_deg,azimuth_deg`).
    Sky(psns::options::SkyArgs),
    /// Sun position (SPA) for a UTC time and place, as CSV `zenith_deg,azimuth_deg`.
    Sun(cli::sun::SunArgs),
    /// Stream raw frames driven by a trajectory to a file, FIFO or stdout (hardware in the loop).
    Stream(cli::stream::StreamArgs),
    /// Turn a psns frame stream into a ROS 2 bag (rosbag2 directory or MCAP file).
    Convert(cli::convert::ConvertArgs),
    /// Be a GigE Vision camera: GenICam clients (Aravis) discover, configure and stream it.
    Gige(cli::gige::GigeArgs),
    /// Check a frame stream: frame count, drops, corrupt and truncated frames. Exit 0 only if clean.
    Verify(cli::verify::VerifyArgs),
    /// Finish what a killed or stopped run left: an unfinished MCAP file or rosbag2 directory
    /// into a finished bag of every complete message, a stream into one of its intact frames.
    Recover(cli::recover::RecoverArgs),
    /// Write one frame of a stream as PNG and TIFF plus its metadata as JSON.
    Extract(cli::verify::ExtractArgs),
    /// Demosaic a raw mosaic (PNG/TIFF) or a stream frame into S0, S1, S2, DoLP, AoLP.
    Demosaic(psns::options::DemosaicArgs),
    /// The camera's yaw from one raw frame's polarization (sun-vector estimator), as CSV.
    Heading(psns::options::HeadingArgs),
    /// Datasets like PSNS: build (sharded, resumable), verify, merge shard manifests.
    Dataset {
        #[command(subcommand)]
        what: psns::options::DatasetCmd,
    },
    /// Benchmarks that chart speed against accuracy.
    Bench {
        #[command(subcommand)]
        what: cli::bench::BenchCmd,
    },
    /// Regenerate the pictures in docs/ (sky sweeps, default camera views).
    Figures(cli::figures::FiguresArgs),
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.cmd {
        Cmd::Render(a) => cli::render::run(a),
        Cmd::Sky(a) => cli::sky::run(a),
        Cmd::Sun(a) => cli::sun::run(a),
        Cmd::Stream(a) => cli::stream::run(a),
        Cmd::Convert(a) => cli::convert::run(a),
        Cmd::Gige(a) => cli::gige::run(a),
        Cmd::Verify(a) => cli::verify::run_verify(a),
        Cmd::Recover(a) => cli::recover::run(a),
        Cmd::Extract(a) => cli::verify::run_extract(a),
        Cmd::Demosaic(a) => cli::demosaic::run(a),
        Cmd::Heading(a) => cli::heading::run(a),
        Cmd::Dataset { what } => cli::dataset::run(what),
        Cmd::Bench { what } => cli::bench::run(what),
        Cmd::Figures(a) => cli::figures::run(a),
    }
}

fn main() -> ExitCode {
    let matches = psns::options::negative_numbers(Cli::command()).get_matches();
    // usage errors exit with code 2
    let cli = Cli::from_arg_matches(&matches).unwrap_or_else(|e| e.exit());
    cli::exit_code(run(cli))
}

#[cfg(test)]
mod tests {
    /// clap's consistency checks (duplicate option names, bad defaults) run only in debug builds
    /// and only when parsing: run them over every command here.
    #[test]
    fn command_line_is_consistent() {
        use clap::CommandFactory;
        psns::options::negative_numbers(super::Cli::command()).debug_assert();
    }
}
