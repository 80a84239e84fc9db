//! [`Plan`]: the samples of a description in canonical order, each drawn from the seed and its
//! position when it is needed, so a plan's memory does not grow with the number of samples.

use super::*;
use rayon::prelude::*;

/// Samples drawn at once (in parallel) when a plan is walked in order: bounds the memory of a
/// walk to a few MB whatever the dataset's size.
const CHUNK: u64 = 8192;

/// The samples of a description in canonical order (split order, then number), position `j`
/// (0-based) to sample. It holds the description and the first position of each split, nothing
/// per sample: [`Plan::sample`] draws sample `j` from the seed and its frame index, as
/// [`DatasetConfig::sample`] does.
#[derive(Clone, Debug)]
pub struct Plan<'a> {
    cfg: &'a DatasetConfig,
    /// The listed splits with their sample counts and first positions.
    splits: Vec<(Split, u64, u64)>,
    len: u64,
}

impl<'a> Plan<'a> {
    /// The plan of `cfg`, not checked (see [`DatasetConfig::plan`]).
    pub fn new(cfg: &'a DatasetConfig) -> Plan<'a> {
        let mut splits = Vec::new();
        let mut len = 0;
        for (s, n) in cfg.split_counts() {
            splits.push((s, n, len));
            len += n;
        }
        Plan { cfg, splits, len }
    }

    /// The description.
    pub fn config(&self) -> &'a DatasetConfig {
        self.cfg
    }

    /// Number of samples.
    pub fn len(&self) -> u64 {
        self.len
    }

    /// Whether the plan has no samples (a validated description has at least one).
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The split and 1-based number of position `j` (`j < len`).
    pub fn id(&self, j: u64) -> (Split, u64) {
        let &(s, _, first) = self
            .splits
            .iter()
            .rev()
            .find(|&&(_, _, first)| first <= j)
            .expect("a plan starts at position 0");
        assert!(
            j < self.len,
            "position {j} of a plan of {} samples",
            self.len
        );
        (s, j - first + 1)
    }

    /// Sample at position `j` (`j < len`).
    pub fn sample(&self, j: u64) -> Result<Sample> {
        let (s, k) = self.id(j);
        self.cfg.sample(s, k)
    }

    /// Positions `j` of shard `shard` (`j mod N = K − 1`), in order.
    pub fn shard_positions(&self, shard: Shard) -> impl IndexedParallelIterator<Item = u64> {
        let first = shard.k - 1;
        let count = if self.len > first {
            (self.len - first).div_ceil(shard.n)
        } else {
            0
        };
        // usize: rayon's indexed ranges (positions are below 2^32)
        (0..count as usize)
            .into_par_iter()
            .map(move |i| first + i as u64 * shard.n)
    }

    /// Calls `each` on every sample in order, drawn in parallel a chunk at a time; stops at the
    /// first error (of a draw, in order, or of `each`).
    pub fn walk<T: Send>(
        &self,
        draw: impl Fn(Sample) -> T + Sync,
        mut each: impl FnMut(T) -> Result<()>,
    ) -> Result<()> {
        let mut start = 0;
        while start < self.len {
            let end = (start + CHUNK).min(self.len);
            let drawn: Vec<Result<T>> = (start as usize..end as usize)
                .into_par_iter()
                .map(|j| self.sample(j as u64).map(&draw))
                .collect();
            for t in drawn {
                each(t?)?;
            }
            start = end;
        }
        Ok(())
    }

    /// Draws every sample that can fail to draw (a `sun_time` that keeps the sun down), and
    /// returns the first failure in order. Without `sun_time` every draw succeeds and nothing is
    /// drawn.
    pub fn check(&self) -> Result<()> {
        if self.cfg.sun_time.is_none() || self.is_empty() {
            return Ok(());
        }
        // a description that keeps the sun down fails on its first sample: fail fast there
        self.sample(0)?;
        self.walk(|_| (), |_| Ok(()))
    }

    /// Writes the labels (`labels.csv`, named `path` in messages): the header and one row per
    /// sample, in order.
    pub fn write_labels(&self, w: &mut dyn std::io::Write, path: &std::path::Path) -> Result<()> {
        let raw12 = self.cfg.outputs.raw12;
        let io = |e| Error::io(format!("writing {}", path.display()), e);
        writeln!(w, "{LABEL_HEADER}").map_err(io)?;
        self.walk(
            |s| s.label_row_with(raw12),
            |row| writeln!(w, "{}", row?).map_err(io),
        )
    }
}

/// PNG bytes per pixel of an 8-bit noisy mosaic, as measured (docs/dataset.md, "Speed and disk
/// space": 3.32 MB per 2448 x 2048 image on average).
const PNG8_BYTES_PER_PIXEL: f64 = 3.32e6 / (2448.0 * 2048.0);
/// PNG bytes per pixel of the 12-bit frame in a 16-bit PNG: the low byte is noise.
const PNG16_BYTES_PER_PIXEL: f64 = 2.0 * PNG8_BYTES_PER_PIXEL;
/// CPU seconds per pixel of one sample, as measured (docs/dataset.md: 0.06 CPU-s per
/// 2448 x 2048 image).
const CPU_SECONDS_PER_PIXEL: f64 = 0.06 / (2448.0 * 2048.0);

/// What a build will do, printed before it starts (and all of a `--dry-run`): the samples of
/// the shard, their files, and estimates of the bytes and the time from the measurements of
/// docs/dataset.md (its machine: 2 cores; another machine, disk or description differs).
#[derive(Clone, Debug, PartialEq)]
pub struct BuildPlan {
    /// The shard.
    pub shard: Shard,
    /// Samples of the shard.
    pub samples: u64,
    /// Samples of the whole dataset.
    pub total_samples: u64,
    /// Files of the shard.
    pub files: u64,
    /// Image size, columns x rows.
    pub size: (usize, usize),
    /// Bytes the shard's files take, estimated.
    pub bytes: f64,
    /// Seconds the shard takes with `jobs` samples at once, estimated.
    pub seconds: f64,
    /// Samples rendered at once.
    pub jobs: usize,
}

impl BuildPlan {
    /// The plan of shard `shard` of `cfg` with `jobs` samples at once.
    ///
    /// ```
    /// use psns::dataset::{BuildPlan, DatasetConfig, Shard};
    /// let p = BuildPlan::new(&DatasetConfig::default(), Shard::ALL, 2);
    /// assert_eq!((p.samples, p.files, p.size), (138_000, 138_000, (2448, 2048)));
    /// assert!((p.bytes / 1e9 - 458.0).abs() < 1.0 && (p.seconds / 3600.0 - 1.15).abs() < 0.01);
    /// let s = BuildPlan::new(&DatasetConfig::default(), Shard { k: 3, n: 4 }, 2);
    /// assert_eq!(s.samples, 34_500);
    /// ```
    pub fn new(cfg: &DatasetConfig, shard: Shard, jobs: usize) -> BuildPlan {
        let total = cfg.total();
        // positions j < total with j mod n = k - 1
        let samples = (total + shard.n - shard.k) / shard.n;
        let px = (cfg.width * cfg.height) as f64;
        let o = &cfg.outputs;
        // the mosaic; the four half-size polarizer images hold as many pixels; the 12-bit frame
        // is another render; the truth is two f32 arrays (npy header 128 bytes)
        let mut bytes = px * PNG8_BYTES_PER_PIXEL;
        let mut cpu = px * CPU_SECONDS_PER_PIXEL;
        let mut files = 1;
        if o.polarizer_images {
            bytes += px * PNG8_BYTES_PER_PIXEL;
            files += 4;
        }
        if o.raw12 {
            bytes += px * PNG16_BYTES_PER_PIXEL;
            cpu += px * CPU_SECONDS_PER_PIXEL;
            files += 1;
        }
        if o.truth {
            bytes += 2.0 * (px * 4.0 + 128.0);
            files += 2;
        }
        let jobs = jobs.max(1);
        BuildPlan {
            shard,
            samples,
            total_samples: total,
            files: samples * files,
            size: (cfg.width, cfg.height),
            bytes: samples as f64 * bytes,
            seconds: samples as f64 * cpu / jobs as f64,
            jobs,
        }
    }
}

impl std::fmt::Display for BuildPlan {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (w, h) = self.size;
        let bytes = match self.bytes {
            b if b >= 1e9 => format!("{:.1} GB", b / 1e9),
            b if b >= 1e6 => format!("{:.1} MB", b / 1e6),
            b => format!("{:.0} kB", (b / 1e3).max(1.0)),
        };
        let time = match self.seconds {
            s if s >= 3600.0 => format!("{:.1} h", s / 3600.0),
            s if s >= 60.0 => format!("{:.0} min", s / 60.0),
            s => format!("{:.0} s", s.max(1.0)),
        };
        let of = if self.shard.n > 1 {
            format!(" (shard {} of {} samples)", self.shard, self.total_samples)
        } else {
            String::new()
        };
        write!(
            f,
            "psns dataset: plan: {} samples of {w} x {h}{of}, {} files, about {bytes}, about {time} \
             with {} at once (estimates from docs/dataset.md's 2-core machine)",
            self.samples, self.files, self.jobs
        )
    }
}
