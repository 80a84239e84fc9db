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
            |row| writeln!(w, "{row}").map_err(io),
        )
    }
}
