//! Options of `psns dataset` (and `psns.dataset_build` in Python).

use crate::dataset::build::{build, load_description, BuildSummary};
use crate::dataset::{DatasetConfig, Shard};
use crate::progress::Reporter;
use crate::{Error, Result};
use clap::{Args, Subcommand};
use std::path::PathBuf;

/// `psns dataset` subcommands.
#[derive(Subcommand)]
pub enum DatasetCmd {
    /// Build a dataset (or one shard of it) into a directory.
    Build(BuildArgs),
    /// Check every file of a dataset against its manifest; exit 0 only if all are present and
    /// intact, else name each missing or damaged file and exit 1.
    Verify(DirArgs),
    /// Write manifest.csv from the shards' manifest parts once every sample is present (a build
    /// does this itself when it finishes the last missing samples).
    Merge(DirArgs),
    /// A contact sheet of a built dataset: one row per folder (canonical order), its first
    /// samples side by side, decimated by an even factor (so one polarizer channel shows).
    Preview(PreviewArgs),
}

/// Options of `psns dataset preview`.
#[derive(Args)]
pub struct PreviewArgs {
    /// Dataset directory.
    pub dir: PathBuf,
    /// Output PNG.
    #[arg(long, value_name = "FILE")]
    pub out: PathBuf,
    /// Samples per folder, 1..20.
    #[arg(long, default_value_t = 3, value_name = "N", value_parser = super::whole)]
    pub per_split: u64,
}

/// Options of `psns dataset build`.
#[derive(Args)]
pub struct BuildArgs {
    /// Dataset directory: new, empty, or holding this same dataset (other shards, a killed run).
    #[arg(long, value_name = "DIR")]
    pub out: PathBuf,
    /// Dataset description (TOML, docs/dataset.md); default: PSNS at full size.
    #[arg(long, value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Build only shard K of N (samples whose position j in the dataset has j mod N = K-1).
    #[arg(long, value_name = "K/N", value_parser = super::parsed::<Shard>)]
    pub shard: Option<Shard>,
    /// Keep the samples already present and intact; render the rest.
    #[arg(long)]
    pub resume: bool,
    /// Samples rendered at once (default: every core), 1..1024.
    #[arg(long, value_name = "N", value_parser = super::integer, allow_negative_numbers = true)]
    pub jobs: Option<i64>,
    /// Check the description and --out, print the plan (samples, bytes, estimated time) and
    /// stop: nothing is created, not even the directory.
    #[arg(long)]
    pub dry_run: bool,
}

/// The dataset directory of `verify` and `merge`.
#[derive(Args)]
pub struct DirArgs {
    /// Dataset directory.
    pub dir: PathBuf,
}

impl BuildArgs {
    /// Builds what these options describe ([`build`]), reporting progress (and first the plan)
    /// to `progress`; `None` for `--dry-run`, which prints the plan only.
    pub fn run(&self, progress: &dyn Reporter) -> Result<Option<BuildSummary>> {
        let cfg = match &self.config {
            Some(p) => load_description(p)?,
            None => DatasetConfig::default(),
        };
        let jobs = match self.jobs {
            None => std::thread::available_parallelism().map_or(1, |n| n.get()),
            Some(j) if (1..=1024).contains(&j) => j as usize,
            Some(j) => return Err(Error::range("jobs", j as f64, "1..1024")),
        };
        build(
            &cfg,
            &self.out,
            self.shard.unwrap_or(Shard::ALL),
            self.resume,
            jobs,
            self.dry_run,
            progress,
        )
    }
}
