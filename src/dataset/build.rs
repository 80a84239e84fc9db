//! Building a dataset (or one shard of it) into a directory: the files of the plan
//! ([`DatasetConfig::plan`]), each rendered by [`RawPipeline`] and written whole.
//!
//! Layout of `DIR`:
//!
//! * `dataset.toml` (the description in force), `labels.csv` (one row per sample, every sample),
//!   `manifest.csv` (size and CRC32 of every file, written when every sample is present);
//! * `NFPI/`, …, `TGNIICPI/`: one 8-bit raw mosaic per sample; `extras/<SPLIT>/`: the optional
//!   outputs;
//! * `.parts/` while a build runs or waits for other shards: `manifest-K-of-N.csv` (one line per
//!   finished file, appended after the file is in place) and `tmp-HOST-PID/` (files being written,
//!   renamed into their folder only when whole). Removed when the manifest is merged.
//!
//! A killed build leaves only whole files in the folders; `resume` keeps a sample when every
//! one of its files is listed in a manifest part (or `manifest.csv`) with the size and CRC32 it
//! has on disk, and renders the others again.

use super::manifest::{
    complete, known_entries, manifest_line, merge, size_crc, write_shared, write_shared_with,
    Merged, DESCRIPTION, EXTRAS, LABELS, MANIFEST, PARTS,
};
use super::{BuildPlan, DatasetConfig, Sample, Shard, Split};
use crate::config::SceneConfig;
use crate::image::Image;
use crate::io::create_dir;
use crate::memory::{check_memory, memory_available, memory_need};
use crate::pipeline::{FrameRequest, RawPipeline};
use crate::progress::{Reporter, Unit};
use crate::{io, Error, Result};
use rayon::prelude::*;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

/// Peak resident bytes per pixel of one sample being rendered (as `render --raw`).
const BYTES_PER_PIXEL: u64 = 90;

/// Reads a dataset description file (missing or unreadable: bad input).
pub fn load_description(path: &Path) -> Result<DatasetConfig> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::input(path, e))?;
    DatasetConfig::from_toml(&text, &format!("config {}", path.display()))
}

/// Checks that `dir` may receive this dataset: new, empty, or holding only what a build of the
/// same description writes.
fn check_out_dir(dir: &Path, cfg_toml: &str) -> Result<()> {
    let bad = |m: String| Error::Invalid(format!("--out {}: {m}", dir.display()));
    if !dir.exists() {
        return Ok(());
    }
    if !dir.is_dir() {
        return Err(bad("exists and is not a directory".into()));
    }
    for e in std::fs::read_dir(dir)
        .map_err(|e| Error::input(dir, e))?
        .flatten()
    {
        let n = e.file_name().to_string_lossy().into_owned();
        let ours = [DESCRIPTION, LABELS, MANIFEST, PARTS, EXTRAS].contains(&n.as_str())
            || Split::ALL.iter().any(|s| s.name() == n)
            || (n.starts_with('.') && n.contains(".tmp-"));
        if !ours {
            return Err(bad(format!(
                "holds '{n}', which psns dataset does not write; give a new or empty directory"
            )));
        }
    }
    if let Ok(old) = std::fs::read_to_string(dir.join(DESCRIPTION)) {
        if old != cfg_toml {
            return Err(bad(
                "holds another dataset (its dataset.toml differs from this description); give a new directory, or the same --config".into(),
            ));
        }
    }
    Ok(())
}

/// This machine's name as it goes into staging directory names `tmp-HOST-PID`.
fn hostname() -> String {
    host_name(std::fs::read_to_string("/proc/sys/kernel/hostname").ok())
}

/// A host name from the kernel's text (`None`, empty or with a `/`: "host"). Hyphens stay: the
/// PID is after the last one.
fn host_name(raw: Option<String>) -> String {
    raw.map(|s| s.trim().to_string())
        .filter(|s| !s.is_empty() && !s.contains('/'))
        .unwrap_or_else(|| "host".into())
}

/// The host and PID of a staging directory name `tmp-HOST-PID`.
fn staging_owner(name: &str) -> Option<(&str, u32)> {
    let (h, pid) = name.strip_prefix("tmp-")?.rsplit_once('-')?;
    Some((h, pid.parse().ok()?))
}

/// Removes the staging directories `.parts/tmp-HOST-PID` of this host's processes that no longer
/// run (a killed build); other hosts' are left alone.
fn remove_stale_staging(dir: &Path) {
    let host = hostname();
    let Ok(entries) = std::fs::read_dir(dir.join(PARTS)) else {
        return;
    };
    for e in entries.flatten() {
        let n = e.file_name().to_string_lossy().into_owned();
        let Some((h, pid)) = staging_owner(&n) else {
            continue;
        };
        let dead = Path::new("/proc/self").exists() && !Path::new(&format!("/proc/{pid}")).exists();
        if h == host && dead {
            let _ = std::fs::remove_dir_all(e.path());
        }
    }
    // hidden temporaries of atomic writes at the top (dataset.toml, labels.csv, manifest.csv):
    // their names carry no host, so only those untouched for two minutes go (another host's
    // write in progress is younger)
    let old = |e: &std::fs::DirEntry| {
        e.metadata()
            .and_then(|m| m.modified())
            .is_ok_and(|t| t.elapsed().is_ok_and(|a| a.as_secs() >= 120))
    };
    if let Ok(entries) = std::fs::read_dir(dir) {
        for e in entries.flatten() {
            let n = e.file_name().to_string_lossy().into_owned();
            let pid = n
                .rsplit_once(".tmp-")
                .and_then(|(_, p)| p.parse::<u32>().ok());
            if n.starts_with('.')
                && old(&e)
                && pid.is_some_and(|p| {
                    Path::new("/proc/self").exists() && !Path::new(&format!("/proc/{p}")).exists()
                })
            {
                let _ = std::fs::remove_file(e.path());
            }
        }
    }
}

/// Renders and writes one sample; returns its manifest lines.
struct Worker<'a> {
    cfg: &'a DatasetConfig,
    dir: &'a Path,
    staging: &'a Path,
    /// The pipelines built so far, shared by the workers.
    cache: &'a PipelineCache,
}

/// The last few pipelines built, by key ([`pipeline_key`]), shared by every worker: rayon starts
/// a fresh worker state for each piece of the sample list it splits off, so a per-worker slot
/// rebuilt the sensor (its relative-illumination map, the camera's fixed patterns) for most
/// samples. A miss builds outside the lock (two workers may both build the same key once).
#[derive(Default)]
struct PipelineCache(Mutex<Vec<(SceneConfig, std::sync::Arc<RawPipeline>)>>);

impl PipelineCache {
    /// Pipelines kept: a few presets and focal lengths at once (a camera pipeline with its maps
    /// is ~100 MB at full size, a PSNS one 20 MB).
    const KEEP: usize = 4;

    fn get(&self, scene: &SceneConfig) -> Result<std::sync::Arc<RawPipeline>> {
        let key = pipeline_key(scene);
        {
            let mut v = self.0.lock().unwrap();
            if let Some(i) = v.iter().position(|(k, _)| *k == key) {
                let e = v.remove(i);
                let p = e.1.clone();
                v.push(e); // most recently used last
                return Ok(p);
            }
        }
        let p = std::sync::Arc::new(RawPipeline::new(&key)?);
        let mut v = self.0.lock().unwrap();
        if v.len() >= Self::KEEP {
            v.remove(0);
        }
        v.push((key, p.clone()));
        Ok(p)
    }
}

/// What decides a pipeline: the scene without the sun, the attitude and the frame index, which
/// [`RawPipeline::stokes`] and [`RawPipeline::frame`] take per frame.
fn pipeline_key(scene: &SceneConfig) -> SceneConfig {
    let mut k = scene.clone();
    k.sun = Default::default();
    k.camera.attitude = Default::default();
    k.raw.frame_index = 0;
    k
}

/// The raw frame of `scene` as `psns render --raw` renders it (same sun, attitude, frame).
///
/// The camera preset keys its pipeline on the whole scene but the sun, attitude and frame index.
/// For the PSNS presets the sensor's costly part (the relative-illumination map of gniipi and
/// gniicpi) depends on the frame size, optics, preset and seed but not on the sky, which changes
/// from sample to sample: that pipeline is kept in the cache keyed also without the sky and
/// renders the sample's sky ([`FrameRequest::under`]). The test that renders every sample again
/// through `psns render` holds both to the same bytes.
fn render(
    cache: &PipelineCache,
    scene: &SceneConfig,
    truth: bool,
) -> Result<(crate::sensor::RawFrame, crate::sensor::mosaic::MosaicLayout)> {
    use crate::sensor::Preset;
    let sun = scene.sun.resolve()?;
    scene.sun.check_up(sun)?;
    let mut key = scene.clone();
    if scene.raw.preset != Preset::Camera {
        key.sky = Default::default();
    }
    let pipe = cache.get(&key)?;
    let mut req = FrameRequest::sky(scene.raw.frame_index, sun, scene.camera.attitude);
    req.truth = truth;
    let f = pipe.render(req.under(&scene.sky))?.frame;
    Ok((f, pipe.sensor_config().layout))
}

impl Worker<'_> {
    /// Writes `name` (relative to the dataset) through the staging directory, then moves it in
    /// place; returns its manifest line.
    fn put(&self, name: &str, write: impl FnOnce(&Path) -> Result<()>) -> Result<String> {
        let tmp = self.staging.join(name.replace('/', "__"));
        write(&tmp)?;
        let (size, crc) =
            size_crc(&tmp).map_err(|e| Error::io(format!("reading {}", tmp.display()), e))?;
        let dst = self.dir.join(name);
        std::fs::rename(&tmp, &dst)
            .map_err(|e| Error::io(format!("moving {} in place", dst.display()), e))?;
        Ok(manifest_line(name, size, crc))
    }

    /// Writes one sample's files; returns their manifest lines and the share of saturated
    /// pixels of its most saturated frame (the preset's, or the 12-bit camera frame).
    fn sample(&mut self, s: &Sample) -> Result<(String, f64)> {
        let o = self.cfg.outputs.clone();
        let files = self.cfg.files(s);
        let mut it = files.iter();
        let mut lines = String::new();
        let scene = s.scene(s.split.preset());
        let (frame, layout) = render(self.cache, &scene, o.truth)?;
        let c = &frame.codes;
        let share = |f: &crate::sensor::RawFrame| {
            let c = &f.codes;
            crate::sensor::saturated_fraction(f.saturated_pixels(), (c.width * c.height) as u64)
        };
        let mut saturated = share(&frame);
        let g = Image::from_vec(c.width, c.height, c.data.iter().map(|&v| v as u8).collect());
        lines += &self.put(it.next().expect("mosaic"), |p| io::write_png_gray8(p, &g))?;
        if o.polarizer_images {
            for a in [0.0, 45.0, 90.0, 135.0] {
                let (r0, c0) = (0..4)
                    .map(|k| (k / 2, k % 2))
                    .find(|&(r, c)| layout.angle_deg(r, c) == a)
                    .expect("layout has every angle");
                let (w, h) = (g.width / 2, g.height / 2);
                let mut sub = Vec::with_capacity(w * h);
                for r in 0..h {
                    for k in 0..w {
                        sub.push(*g.get(2 * r + r0, 2 * k + c0));
                    }
                }
                let sub = Image::from_vec(w, h, sub);
                lines += &self.put(it.next().expect("pol"), |p| io::write_png_gray8(p, &sub))?;
            }
        }
        if o.raw12 {
            let scene12 = s.scene(crate::sensor::Preset::Camera);
            let (f12, _) = render(self.cache, &scene12, false)?;
            saturated = saturated.max(share(&f12));
            lines += &self.put(it.next().expect("raw12"), |p| {
                io::write_png_gray16(p, &f12.codes)
            })?;
        }
        if o.truth {
            let (dop, aop) = frame.truth_dolp_aolp();
            lines += &self.put(it.next().expect("dop"), |p| io::write_npy(p, &dop))?;
            lines += &self.put(it.next().expect("aop"), |p| io::write_npy(p, &aop))?;
        }
        Ok((lines, saturated))
    }
}

/// The lock of one shard's build: `.parts/lock-K-of-N`, held with an exclusive `flock` for the
/// whole build and holding the holder's host and PID. The kernel drops the lock when its holder
/// ends, so the lock of a killed build is taken over by the next one; the file itself is only a
/// name to lock and a note of who holds it.
struct ShardLock {
    file: std::fs::File,
    path: PathBuf,
}

impl ShardLock {
    fn take(dir: &Path, shard: Shard) -> Result<ShardLock> {
        let path = dir
            .join(PARTS)
            .join(format!("lock-{}-of-{}", shard.k, shard.n));
        let ctx = || format!("locking {}", path.display());
        let mut file = std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .create(true)
            .truncate(false)
            .open(&path)
            .map_err(|e| Error::io(ctx(), e))?;
        match file.try_lock() {
            Ok(()) => {}
            Err(std::fs::TryLockError::WouldBlock) => {
                let holder = std::fs::read_to_string(&path).unwrap_or_default();
                let what = if shard.n == 1 {
                    "this dataset".to_string()
                } else {
                    format!("shard {shard} of this dataset")
                };
                return Err(Error::Invalid(format!(
                    "{what} is being built into {} by {} (lock {}); wait for it to end, or stop it",
                    dir.display(),
                    match holder.trim() {
                        "" => "another process".to_string(),
                        h => format!("process {h}"),
                    },
                    path.display()
                )));
            }
            Err(std::fs::TryLockError::Error(e)) => return Err(Error::io(ctx(), e)),
        }
        let note = format!("{} on {}\n", std::process::id(), hostname());
        file.set_len(0)
            .and_then(|_| file.write_all(note.as_bytes()))
            .map_err(|e| Error::io(ctx(), e))?;
        Ok(ShardLock { file, path })
    }

    /// Removes the lock file (while still holding it), then `.parts` if that leaves it empty.
    fn release(self) {
        let _ = std::fs::remove_file(&self.path);
        if let Some(parts) = self.path.parent() {
            let _ = std::fs::remove_dir(parts);
        }
        drop(self.file);
    }
}

/// How a build went ([`build`]); its `Display` is the summary `psns dataset build` prints.
#[derive(Clone, Debug)]
pub struct BuildSummary {
    /// The dataset directory.
    pub dir: PathBuf,
    /// The shard built.
    pub shard: Shard,
    /// Samples rendered and written by this run.
    pub built: usize,
    /// Files written by this run.
    pub files: usize,
    /// Samples found complete and kept (`resume`).
    pub skipped: usize,
    /// Samples built by this run with more than
    /// [`SATURATION_WARN_FRACTION`](crate::sensor::SATURATION_WARN_FRACTION) of their pixels
    /// saturated.
    pub saturated_samples: usize,
    /// The largest share of saturated pixels of a sample built by this run.
    pub worst_saturated_fraction: f64,
    /// Seconds spent rendering and writing.
    pub seconds: f64,
    /// Seconds with start-up (description, plan, checks).
    pub total_seconds: f64,
    /// Samples of the whole dataset.
    pub total_samples: u64,
    /// Whether `manifest.csv` could be written.
    pub merged: Merged,
}

impl std::fmt::Display for BuildSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let (shard, built, skipped, secs) = (self.shard, self.built, self.skipped, self.seconds);
        let rate = if secs > 0.0 { built as f64 / secs } else { 0.0 };
        writeln!(
            f,
            "psns dataset: shard {shard}: built {built} samples ({} files), {skipped} already complete, in {secs:.2} s: {rate:.2} images/s ({:.2} s with start-up)",
            self.files, self.total_seconds
        )?;
        if self.saturated_samples > 0 {
            writeln!(
                f,
                "psns dataset: warning: {} of {built} samples have more than {} % of their pixels \
                 saturated (worst {:.1} %): they carry no polarization there; shorten the \
                 exposure (raw12_exposure_us) or use auto-exposure",
                self.saturated_samples,
                100.0 * crate::sensor::SATURATION_WARN_FRACTION,
                100.0 * self.worst_saturated_fraction
            )?;
        }
        match &self.merged {
            Merged::Written { files } => write!(
                f,
                "psns dataset: {} samples complete; wrote {} ({files} files)",
                self.total_samples,
                self.dir.join(MANIFEST).display()
            ),
            Merged::Missing { samples, .. } if self.shard.n == 1 => write!(
                f,
                "psns dataset: {samples} of {} samples are missing or damaged (changed while this build ran); run the build again with --resume to complete {}",
                self.total_samples,
                self.dir.display()
            ),
            Merged::Missing { samples, .. } => write!(
                f,
                "psns dataset: {samples} of {} samples are not built yet (other shards); the last shard to finish writes manifest.csv, or run psns dataset merge {}",
                self.total_samples,
                self.dir.display()
            ),
        }
    }
}

/// Builds shard `shard` of the dataset `cfg` into `dir` with `jobs` samples rendered at once;
/// `resume` keeps the samples already present and intact. Everything is checked before the
/// first file is written, then the plan ([`BuildPlan`]: samples, bytes, estimated time) is
/// printed on `progress`; with `dry_run` that is all (`None`: nothing is created, not even
/// `dir`). The last shard to finish writes `manifest.csv`.
pub fn build(
    cfg: &DatasetConfig,
    dir: &Path,
    shard: Shard,
    resume: bool,
    jobs: usize,
    dry_run: bool,
    progress: &dyn Reporter,
) -> Result<Option<BuildSummary>> {
    let t0 = Instant::now();
    let cfg_toml = cfg.to_toml();
    let dir = dir.to_path_buf();
    check_out_dir(&dir, &cfg_toml)?;
    check_memory(
        &format!("{jobs} samples of {} x {} at once", cfg.width, cfg.height),
        memory_need(cfg.width * cfg.height * jobs, BYTES_PER_PIXEL),
        memory_available(),
    )?;
    // every sample can be drawn (a sun_time that keeps the sun down fails here); samples are
    // drawn again from their position when needed, so the plan holds nothing per sample
    let plan = cfg.plan()?;
    let estimate = BuildPlan::new(cfg, shard, jobs);
    progress
        .start("psns dataset", Unit::Images, None, false)
        .println(&estimate.to_string());
    if dry_run {
        return Ok(None);
    }
    // everything is checked: from here on files are written
    let mut dirs: Vec<PathBuf> = vec![dir.join(PARTS)];
    for (s, _) in cfg.split_counts() {
        dirs.push(dir.join(s.name()));
        if cfg.outputs != Default::default() {
            dirs.push(dir.join(EXTRAS).join(s.name()));
        }
    }
    for d in &dirs {
        create_dir(d)?;
    }
    // one build per shard at a time; a lock whose holder died is taken over
    let lock = ShardLock::take(&dir, shard)?;
    remove_stale_staging(&dir);
    write_shared(&dir.join(DESCRIPTION), &cfg_toml)?;
    let labels = dir.join(LABELS);
    write_shared_with(&labels, |w| plan.write_labels(w, &labels).map(|_| true))?;
    let part_path = dir
        .join(PARTS)
        .join(format!("manifest-{}-of-{}.csv", shard.k, shard.n));
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs)
        .build()
        .map_err(|e| Error::io(format!("starting {jobs} threads"), std::io::Error::other(e)))?;
    let n_mine = plan.shard_positions(shard).len();
    // --resume: the positions still to render, 4 bytes each (positions are below 2^32: a
    // description holds at most 6 · 10⁷ samples); None: every position of the shard
    let todo: Option<Vec<u32>> = if resume {
        let (known, _) = known_entries(&dir);
        // reading every file back takes a while on a big dataset: show it
        let checked = Mutex::new(progress.start(
            "psns dataset: --resume: checking",
            Unit::Images,
            Some(n_mine as u64),
            false,
        ));
        let todo: Result<Vec<u32>> = pool.install(|| {
            plan.shard_positions(shard)
                .map(|j| {
                    let whole = complete(&dir, &cfg.files(&plan.sample(j)?), &known);
                    checked.lock().unwrap().inc(1);
                    Ok((!whole).then_some(j as u32))
                })
                .filter_map(|r: Result<Option<u32>>| r.transpose())
                .collect()
        });
        Some(todo?)
    } else {
        None
    };
    let n_todo = todo.as_ref().map_or(n_mine, |t| t.len());
    let skipped = n_mine - n_todo;
    let part = std::fs::OpenOptions::new()
        .create(true)
        .append(resume)
        .write(true)
        .truncate(!resume)
        .open(&part_path)
        .map_err(|e| Error::io(format!("opening {}", part_path.display()), e))?;
    // a line cut by a kill is ended, so the next entry starts a line of its own
    let cut = std::fs::read(&part_path).is_ok_and(|b| b.last().is_some_and(|&c| c != b'\n'));
    let mut part = part;
    if cut {
        part.write_all(b"\n")
            .map_err(|e| Error::io(format!("writing {}", part_path.display()), e))?;
    }
    let part = Mutex::new(part);
    let staging = dir
        .join(PARTS)
        .join(format!("tmp-{}-{}", hostname(), std::process::id()));
    create_dir(&staging)?;
    let progress =
        Mutex::new(progress.start("psns dataset", Unit::Images, Some(n_todo as u64), true));
    if skipped > 0 {
        progress.lock().unwrap().println(&format!(
            "psns dataset: --resume: {skipped} samples already complete"
        ));
    }
    let cache = PipelineCache::default();
    let t1 = Instant::now();
    // (samples over the saturation warning's share, the largest share)
    let saturation = Mutex::new((0usize, 0.0f64));
    let render_one = |w: &mut Worker, j: u64| -> Result<()> {
        let s = plan.sample(j)?;
        let (lines, sat) = w.sample(&s)?;
        {
            let mut m = saturation.lock().unwrap();
            m.0 += usize::from(sat > crate::sensor::SATURATION_WARN_FRACTION);
            m.1 = m.1.max(sat);
        }
        part.lock()
            .unwrap()
            .write_all(lines.as_bytes())
            .map_err(|e| Error::io(format!("writing {}", part_path.display()), e))?;
        let mut p = progress.lock().unwrap();
        p.set_message(s.split.name());
        p.inc(1);
        Ok(())
    };
    let worker = || Worker {
        cfg,
        dir: &dir,
        staging: &staging,
        cache: &cache,
    };
    let result: Result<()> = pool.install(|| match &todo {
        Some(t) => t
            .par_iter()
            .try_for_each_init(worker, |w, &j| render_one(w, j as u64)),
        None => plan
            .shard_positions(shard)
            .try_for_each_init(worker, render_one),
    });
    drop(progress);
    let _ = std::fs::remove_dir(&staging);
    result?;
    let seconds = t1.elapsed().as_secs_f64();
    let built = n_todo;
    let files = built * cfg.files(&plan.sample(0)?).len();
    let total_seconds = t0.elapsed().as_secs_f64();
    let merged = merge(&dir, &plan)?;
    lock.release();
    let (saturated_samples, worst_saturated_fraction) = *saturation.lock().unwrap();
    Ok(Some(BuildSummary {
        dir,
        shard,
        built,
        files,
        skipped,
        saturated_samples,
        worst_saturated_fraction,
        seconds,
        total_seconds,
        total_samples: cfg.total(),
        merged,
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Staging directories of hosts named with hyphens (node-012) are told apart from other
    /// hosts' (the first version mapped every such name to "host", so a build on one node
    /// removed another node's staging).
    #[test]
    fn staging_names_keep_the_host() {
        assert_eq!(host_name(Some("node-012\n".into())), "node-012");
        assert_eq!(host_name(Some("".into())), "host");
        assert_eq!(host_name(None), "host");
        assert_eq!(staging_owner("tmp-node-012-4242"), Some(("node-012", 4242)));
        assert_eq!(staging_owner("tmp-a-1"), Some(("a", 1)));
        assert_eq!(staging_owner("manifest-1-of-3.csv"), None);
        assert_eq!(staging_owner("tmp-node-x"), None);
    }
}
