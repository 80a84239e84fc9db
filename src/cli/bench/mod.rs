//! `psns bench`: benchmarks that chart speed against accuracy, with the named benchmark scenes
//! ([`scenes`]) and their charts. Front-end code: the measurements call the library's kernels.

pub mod budget;
pub mod demosaic;
pub mod error_maps;
pub mod gige;
pub mod heading;
pub mod scenes;
pub mod sky;
pub mod stream;
pub mod stream_cpu;
#[cfg(test)]
mod tests;
pub mod tolerance;
pub mod world;

use clap::Subcommand;
use psns::options::SceneArgs;
use std::path::PathBuf;

/// `psns bench` subcommands.
#[derive(Subcommand)]
pub enum BenchCmd {
    /// Time every demosaic method on full-size frames and score it on the named scenes; writes
    /// demosaic.csv, the speed-vs-accuracy chart and stability maps.
    Demosaic {
        /// Output directory (regenerate the docs' numbers with `--out docs/bench`).
        #[arg(long, default_value = "out-bench")]
        out: PathBuf,
        /// Timed runs per method (median reported).
        #[arg(long, default_value_t = 7, value_parser = psns::options::runs)]
        runs: usize,
        /// Small frames and few runs (a quick look; refused with an --out inside docs/).
        #[arg(long)]
        quick: bool,
    },
    /// The heading chain end to end: every estimator against the truth over sun elevation, yaw,
    /// turbidity, exposure, clouds, demosaic, bit depth, tilt and DoLP, one factor at a time around
    /// a baseline (612 x 512 frames); writes heading.csv, heading_frames.csv and two SVG charts.
    Heading {
        /// Output directory (the docs' charts: `--out docs/bench`).
        #[arg(long, default_value = "out-bench")]
        out: PathBuf,
        /// Small frames, two yaws, two values per factor (refused with an --out inside docs/).
        #[arg(long)]
        quick: bool,
        /// The error budget instead of the sweep: each source of yaw error (noise, quantisation,
        /// demosaic, sky-model mismatch, IMU tilt error, lens model, clouds) alone and end to
        /// end, for every estimator on its own and every other sky model; writes budget.csv,
        /// budget_summary.csv, budget_frames.csv, budget_panfit.csv and budget.svg.
        #[arg(long)]
        budget: bool,
        /// How far each input of `psns heading` (tilt, sun, focal length, principal point,
        /// projection, lens, bit depth) can be wrong before the confidence falls below 0.5, and
        /// the yaw error there, on the default scene; writes tolerance.csv, tolerance.md and
        /// tolerance_scan.csv.
        #[arg(long, conflicts_with = "budget")]
        tolerance: bool,
        /// Each estimator's yaw error where the sky is cut, with the mask found from the frame
        /// and without: street canyons, skylines, trees and cloud cover seen by a zenith
        /// equidistant fisheye, over twelve yaws; writes world.csv, world_summary.csv and
        /// world.svg.
        #[arg(long, conflicts_with_all = ["budget", "tolerance"])]
        world: bool,
    },
    /// Frames/s an Aravis receiver (arv-camera-test-0.8 -f 200 -i 8192) gets from psns gige on
    /// this machine, Mono8, Mono16 and under DeviceLinkThroughputLimit, against Aravis's fake
    /// camera, with each side's CPU time (writes gige.csv and gige.md). Needs aravis-tools.
    Gige {
        /// Output directory (the docs' table: `--out docs/bench`).
        #[arg(long, default_value = "out-bench")]
        out: PathBuf,
        /// Seconds per receiver run.
        #[arg(long, default_value_t = 12, value_parser = clap::value_parser!(u32).range(4..=600))]
        duration: u32,
        /// Runs per case (median reported, with the slowest and fastest).
        #[arg(long, default_value_t = 3, value_parser = psns::options::runs)]
        runs: usize,
    },
    /// Exact vs coarse-grid sky evaluation: time per full frame and error (writes sky_grid.csv).
    Sky {
        #[command(flatten)]
        scene: SceneArgs,
        /// Output directory (regenerate the docs' numbers with `--out docs/bench`).
        #[arg(long, default_value = "out-bench")]
        out: PathBuf,
        /// Timed runs per setting (median reported).
        #[arg(long, default_value_t = 5, value_parser = psns::options::runs)]
        runs: usize,
    },
    /// Stream frames/s per stage (sky, sensor, packing, write) and end to end, fast path against
    /// --exact, and the stream's speed targets (writes stream_stages.csv, stream_e2e.csv,
    /// stream_targets.csv, stream_accuracy.csv and the chart).
    Stream {
        #[command(flatten)]
        scene: SceneArgs,
        /// Output directory (regenerate the docs' numbers with `--out docs/bench`).
        #[arg(long, default_value = "out-bench")]
        out: PathBuf,
        /// Frames per stage measurement (median reported).
        #[arg(long, default_value_t = 20, value_parser = psns::options::runs)]
        frames: usize,
        /// Frames per end-to-end run of `psns stream` (a third of them with --exact).
        #[arg(long, default_value_t = 300, value_parser = psns::options::runs)]
        e2e_frames: usize,
        /// End-to-end runs per command (median reported, with the slowest and fastest run).
        #[arg(long, default_value_t = 3, value_parser = psns::options::runs)]
        runs: usize,
        /// Sky grid steps of the fast path to time.
        #[arg(long, value_delimiter = ',', default_values_t = vec![8usize, 16, 32])]
        steps: Vec<usize>,
        /// Only CPU time per frame (user + system): the stages and whole `psns stream` runs, at
        /// the AVX2 level and the best the CPU has (writes stream_cpu_stages.csv, stream_cpu.csv).
        #[arg(long)]
        cpu: bool,
        /// With --cpu: a psns binary to run side by side, alternated run by run (e.g. an earlier
        /// commit's target/release/psns); the table gives the ratio.
        #[arg(long, requires = "cpu", value_name = "PATH")]
        baseline: Option<PathBuf>,
        /// Print the fast path's stage CPU times at this process's level and exit (the child
        /// process of --cpu).
        #[arg(long, hide = true)]
        stages_child: bool,
    },
}

/// Runs a `psns bench` subcommand.
pub fn run(what: BenchCmd) -> anyhow::Result<()> {
    match what {
        BenchCmd::Demosaic { out, runs, quick } => {
            let opts = demosaic::BenchOptions { out, runs, quick };
            for f in demosaic::bench_demosaic(&opts)? {
                eprintln!("wrote {f}");
            }
        }
        BenchCmd::Stream {
            scene,
            out,
            frames,
            e2e_frames,
            runs,
            steps,
            cpu,
            baseline,
            stages_child,
        } => {
            let cfg = scene.scene()?;
            if stages_child {
                let t = stream::stage_times(&cfg, Some(16), frames)?;
                let [s, n, p] = t.cpu_ms;
                println!("{s:.3},{n:.3},{p:.3},{:.3}", s + n + p);
                return Ok(());
            }
            if cpu {
                let opts = stream_cpu::CpuOptions {
                    out,
                    frames,
                    e2e_frames,
                    runs,
                    baseline,
                };
                for f in stream_cpu::bench_cpu(&cfg, &opts)? {
                    eprintln!("wrote {f}");
                }
                return Ok(());
            }
            let opts = stream::StreamBenchOptions {
                out,
                frames,
                e2e_frames,
                runs,
                steps,
            };
            for f in stream::bench_stream(&cfg, &opts)? {
                eprintln!("wrote {f}");
            }
        }
        BenchCmd::Gige {
            out,
            duration,
            runs,
        } => {
            let opts = gige::GigeBenchOptions {
                out,
                duration_s: duration,
                runs,
            };
            for f in gige::bench_gige(&opts)? {
                eprintln!("wrote {f}");
            }
        }
        BenchCmd::Heading {
            out,
            quick,
            budget,
            tolerance,
            world,
        } => {
            let written = if world {
                world::bench_world(&world::WorldOptions { out, quick })?
            } else if budget {
                budget::bench_budget(&budget::BudgetOptions { out, quick })?
            } else if tolerance {
                tolerance::bench_tolerance(&tolerance::ToleranceOptions { out, quick })?
            } else {
                heading::bench_heading(&heading::HeadingBenchOptions { out, quick })?
            };
            for f in written {
                eprintln!("wrote {f}");
            }
        }
        BenchCmd::Sky { scene, out, runs } => {
            let cfg = scene.scene()?;
            for f in sky::bench_sky_to_dir(&cfg, &out, runs)? {
                eprintln!("wrote {f}");
            }
        }
    }
    Ok(())
}
