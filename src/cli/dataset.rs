//! `psns dataset build | verify | merge`: PSNS-style datasets from a description (issue 11).
//!
//! The plan (parameters, names, labels) is the library's [`psns::dataset`]; this file does the
//! files. Layout of `DIR`:
//!
//! * `dataset.toml` (the description in force), `labels.csv` (one row per sample, every sample),
//!   `manifest.csv` (size and CRC32 of every file, written when every sample is present);
//! * `NFPI/`, …, `TGNIICPI/`: one 8-bit raw mosaic per sample; `extras/<SPLIT>/`: the optional
//!   outputs;
//! * `.parts/` while a build runs or waits for other shards: `manifest-K-of-N.csv` (one line per
//!   finished file, appended after the file is in place) and `tmp-HOST-PID/` (files being written,
//!   renamed into their folder only when whole). Removed when the manifest is merged.
//!
//! A killed build leaves only whole files in the folders; `--resume` keeps a sample when every
//! one of its files is listed in a manifest part (or `manifest.csv`) with the size and CRC32 it
//! has on disk, and renders the others again.

use super::progress::{Progress, Unit};
use clap::{Args, Subcommand};
use psns::config::SceneConfig;
use psns::dataset::{DatasetConfig, Sample, Shard, Split, LABEL_HEADER};
use psns::image::Image;
use psns::pipeline::RawPipeline;
use psns::{io, Error, Result};
use rayon::prelude::*;
use std::collections::HashMap;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::sync::Mutex;
use std::time::Instant;

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
    dir: PathBuf,
    /// Output PNG.
    #[arg(long, value_name = "FILE")]
    out: PathBuf,
    /// Samples per folder, 1..20.
    #[arg(long, default_value_t = 3, value_name = "N")]
    per_split: u64,
}

/// Options of `psns dataset build`.
#[derive(Args)]
pub struct BuildArgs {
    /// Dataset directory: new, empty, or holding this same dataset (other shards, a killed run).
    #[arg(long, value_name = "DIR")]
    out: PathBuf,
    /// Dataset description (TOML, docs/dataset.md); default: PSNS at full size.
    #[arg(long, value_name = "FILE")]
    config: Option<PathBuf>,
    /// Build only shard K of N (samples whose position j in the dataset has j mod N = K-1).
    #[arg(long, value_name = "K/N", value_parser = parse_shard)]
    shard: Option<Shard>,
    /// Keep the samples already present and intact; render the rest.
    #[arg(long)]
    resume: bool,
    /// Samples rendered at once (default: every core), 1..1024.
    #[arg(long, value_name = "N", allow_negative_numbers = true)]
    jobs: Option<i64>,
}

/// The dataset directory of `verify` and `merge`.
#[derive(Args)]
pub struct DirArgs {
    /// Dataset directory.
    dir: PathBuf,
}

fn parse_shard(s: &str) -> std::result::Result<Shard, String> {
    s.parse().map_err(|e: Error| e.to_string())
}

/// The dataset is not intact (exit code 1; the damaged files were listed on stdout).
#[derive(Debug)]
pub struct Damaged(String);
impl std::fmt::Display for Damaged {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}
impl std::error::Error for Damaged {}

/// Runs `psns dataset ...`.
pub fn run(cmd: DatasetCmd) -> anyhow::Result<()> {
    match cmd {
        DatasetCmd::Build(a) => build(a),
        DatasetCmd::Verify(a) => verify(&a.dir),
        DatasetCmd::Merge(a) => merge_cmd(&a.dir),
        DatasetCmd::Preview(a) => preview(&a),
    }
}

const DESCRIPTION: &str = "dataset.toml";
const LABELS: &str = "labels.csv";
const MANIFEST: &str = "manifest.csv";
const PARTS: &str = ".parts";
const EXTRAS: &str = "extras";
/// Peak resident bytes per pixel of one sample being rendered (as `render --raw`).
const BYTES_PER_PIXEL: u64 = 90;

/// Reads a dataset description file (missing or unreadable: bad input).
fn load_config(path: &Path) -> Result<DatasetConfig> {
    let text = std::fs::read_to_string(path).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => {
            Error::Invalid(format!("config file {} does not exist", path.display()))
        }
        _ => Error::input(path, e),
    })?;
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

/// Writes a file every shard writes with the same content (atomically), unless it is already
/// there with that content: shards starting or finishing together then rarely write at once.
fn write_shared(path: &Path, text: &str) -> Result<()> {
    if std::fs::read(path).is_ok_and(|b| b == text.as_bytes()) {
        return Ok(());
    }
    super::write_text(path, text)
}

/// Size and CRC32 of a file.
fn size_crc(path: &Path) -> std::io::Result<(u64, u32)> {
    let mut f = std::fs::File::open(path)?;
    let mut h = crc32fast::Hasher::new();
    let mut buf = vec![0u8; 1 << 20];
    let mut n = 0u64;
    loop {
        let k = f.read(&mut buf)?;
        if k == 0 {
            break;
        }
        h.update(&buf[..k]);
        n += k as u64;
    }
    Ok((n, h.finalize()))
}

/// A manifest line `file,size,crc32` (CRC in 8 hex digits).
fn manifest_line(file: &str, size: u64, crc: u32) -> String {
    format!("{file},{size},{crc:08x}\n")
}

/// One manifest line `file,size,crc32` (8 hex digits), or `None` (the header, a line cut by a
/// kill, damage).
fn parse_line(line: &str) -> Option<(String, u64, u32)> {
    let mut it = line.rsplitn(3, ',');
    let (crc, size, file) = (it.next()?, it.next()?, it.next()?);
    if crc.len() != 8 || file.is_empty() || file.contains(',') {
        return None;
    }
    Some((
        file.to_string(),
        size.parse().ok()?,
        u32::from_str_radix(crc, 16).ok()?,
    ))
}

/// Entries of a manifest or manifest part; lines that do not parse are skipped.
fn read_entries(text: &str, into: &mut HashMap<String, (u64, u32)>) {
    for (f, size, crc) in text.lines().filter_map(parse_line) {
        into.insert(f, (size, crc));
    }
}

/// Every entry known in `dir`: `manifest.csv` and then every part (a later entry wins). Also
/// returns the part files read.
fn known_entries(dir: &Path) -> (HashMap<String, (u64, u32)>, Vec<PathBuf>) {
    let mut m = HashMap::new();
    if let Ok(t) = std::fs::read_to_string(dir.join(MANIFEST)) {
        read_entries(&t, &mut m);
    }
    let mut parts = Vec::new();
    if let Ok(entries) = std::fs::read_dir(dir.join(PARTS)) {
        let mut names: Vec<PathBuf> = entries
            .flatten()
            .map(|e| e.path())
            .filter(|p| {
                p.is_file()
                    && p.file_name()
                        .is_some_and(|n| n.to_string_lossy().starts_with("manifest-"))
            })
            .collect();
        names.sort();
        for p in names {
            if let Ok(t) = std::fs::read_to_string(&p) {
                read_entries(&t, &mut m);
                parts.push(p);
            }
        }
    }
    (m, parts)
}

/// Whether every file of `s` is on disk with the size and CRC32 an entry records.
fn complete(dir: &Path, files: &[String], known: &HashMap<String, (u64, u32)>) -> bool {
    files.iter().all(|f| match known.get(f) {
        Some(&want) => size_crc(&dir.join(f)).is_ok_and(|got| got == want),
        None => false,
    })
}

/// How a merge went.
enum Merged {
    Written { files: usize },
    Missing { samples: u64, first: String },
}

/// Writes `manifest.csv` when every file of every sample has an entry; then removes `.parts`.
fn merge(dir: &Path, cfg: &DatasetConfig, plan: &[Sample]) -> Result<Merged> {
    let (known, parts) = known_entries(dir);
    let mut text = String::from("file,size,crc32\n");
    for name in [DESCRIPTION, LABELS] {
        let p = dir.join(name);
        let (size, crc) =
            size_crc(&p).map_err(|e| Error::io(format!("reading {}", p.display()), e))?;
        text.push_str(&manifest_line(name, size, crc));
    }
    let (mut missing, mut first) = (0u64, String::new());
    let mut files = 2;
    for s in plan {
        let fs = cfg.files(s);
        let mut whole = true;
        for f in &fs {
            match known.get(f) {
                Some(&(size, crc)) => text.push_str(&manifest_line(f, size, crc)),
                None => whole = false,
            }
        }
        if !whole {
            if missing == 0 {
                first = fs[0].clone();
            }
            missing += 1;
        }
        files += fs.len();
    }
    if missing > 0 {
        return Ok(Merged::Missing {
            samples: missing,
            first,
        });
    }
    write_shared(&dir.join(MANIFEST), &text)?;
    for p in parts {
        let _ = std::fs::remove_file(p);
    }
    // other shards on other hosts are done too (every sample is in): their staging is empty
    if let Ok(entries) = std::fs::read_dir(dir.join(PARTS)) {
        for e in entries.flatten() {
            let _ = std::fs::remove_dir(e.path()); // only empty ones
        }
    }
    let _ = std::fs::remove_dir(dir.join(PARTS));
    Ok(Merged::Written { files })
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
/// renders the sample's sky ([`RawPipeline::frame_at_in`]: read row by row from the sky grid,
/// the codes of `psns render`'s planes; with `truth`, [`RawPipeline::stokes_in`]'s planes, which
/// the truth needs). The test that renders every sample again through `psns render` holds both
/// to the same bytes.
fn render(
    cache: &PipelineCache,
    scene: &SceneConfig,
    truth: bool,
) -> Result<(psns::sensor::RawFrame, psns::sensor::mosaic::MosaicLayout)> {
    use psns::sensor::Preset;
    let sun = scene.sun.resolve()?;
    scene.sun.check_up(sun)?;
    let attitude = &scene.camera.attitude;
    let index = scene.raw.frame_index;
    let (pipe, f) = if scene.raw.preset == Preset::Camera {
        let pipe = cache.get(scene)?;
        let (st, _) = pipe.stokes(sun, attitude)?;
        // the path psns render --raw takes, so the images re-render byte for byte
        let f = pipe.frame_of(&st, index, truth)?;
        (pipe, f)
    } else {
        let mut key = scene.clone();
        key.sky = Default::default();
        let pipe = cache.get(&key)?;
        let f = if truth {
            let (st, _) = pipe.stokes_in(&scene.sky, sun, attitude)?;
            pipe.frame_of(&st, index, true)?
        } else {
            pipe.frame_at_in(&scene.sky, sun, attitude, index, Vec::new())?
                .0
        };
        (pipe, f)
    };
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

    fn sample(&mut self, s: &Sample) -> Result<String> {
        let o = self.cfg.outputs.clone();
        let files = self.cfg.files(s);
        let mut it = files.iter();
        let mut lines = String::new();
        let scene = s.scene(s.split.preset());
        let (frame, layout) = render(self.cache, &scene, o.truth)?;
        let c = &frame.codes;
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
            let scene12 = s.scene(psns::sensor::Preset::Camera);
            let (f12, _) = render(self.cache, &scene12, false)?;
            lines += &self.put(it.next().expect("raw12"), |p| {
                io::write_png_gray16(p, &f12.codes)
            })?;
        }
        if o.truth {
            let (dop, aop) = frame.truth_dolp_aolp();
            lines += &self.put(it.next().expect("dop"), |p| io::write_npy(p, &dop))?;
            lines += &self.put(it.next().expect("aop"), |p| io::write_npy(p, &aop))?;
        }
        Ok(lines)
    }
}

fn build(a: BuildArgs) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let cfg = match &a.config {
        Some(p) => load_config(p)?,
        None => DatasetConfig::default(),
    };
    let shard = a.shard.unwrap_or(Shard::ALL);
    let jobs = match a.jobs {
        None => std::thread::available_parallelism().map_or(1, |n| n.get()),
        Some(j) if (1..=1024).contains(&j) => j as usize,
        Some(j) => return Err(Error::range("jobs", j as f64, "1..1024").into()),
    };
    let cfg_toml = cfg.to_toml();
    let dir = a.out.clone();
    check_out_dir(&dir, &cfg_toml)?;
    super::output::check_memory(
        &format!("{jobs} samples of {} x {} at once", cfg.width, cfg.height),
        super::output::memory_need(cfg.width * cfg.height * jobs, BYTES_PER_PIXEL),
        super::output::memory_available(),
    )?;
    // every sample's parameters and name (a sun_time that keeps the sun down fails here)
    let plan = cfg.plan()?;
    let mut labels = String::with_capacity(plan.len() * 200);
    labels.push_str(LABEL_HEADER);
    labels.push('\n');
    let mut mine = Vec::new();
    for (j, s) in plan.iter().enumerate() {
        labels.push_str(&s.label_row_with(cfg.outputs.raw12));
        labels.push('\n');
        if shard.contains(j as u64) {
            mine.push(s.clone());
        }
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
        super::create_dir(d)?;
    }
    remove_stale_staging(&dir);
    write_shared(&dir.join(DESCRIPTION), &cfg_toml)?;
    write_shared(&dir.join(LABELS), &labels)?;
    drop(labels);
    let part_path = dir
        .join(PARTS)
        .join(format!("manifest-{}-of-{}.csv", shard.k, shard.n));
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs)
        .build()
        .map_err(|e| anyhow::anyhow!("starting {jobs} threads: {e}"))?;
    let n_mine = mine.len();
    let todo: Vec<Sample> = if a.resume {
        let (known, _) = known_entries(&dir);
        // reading every file back takes a while on a big dataset: show it
        let checked = Mutex::new(Progress::new(
            "psns dataset: --resume: checking",
            Unit::Images,
            Some(mine.len() as u64),
            false,
        ));
        pool.install(|| {
            mine.into_par_iter()
                .filter(|s| {
                    let whole = complete(&dir, &cfg.files(s), &known);
                    checked.lock().unwrap().inc(1);
                    !whole
                })
                .collect()
        })
    } else {
        mine
    };
    let skipped = n_mine - todo.len();
    let part = std::fs::OpenOptions::new()
        .create(true)
        .append(a.resume)
        .write(true)
        .truncate(!a.resume)
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
    super::create_dir(&staging)?;
    let progress = Mutex::new(Progress::new(
        "psns dataset",
        Unit::Images,
        Some(todo.len() as u64),
        true,
    ));
    if skipped > 0 {
        progress.lock().unwrap().println(format!(
            "psns dataset: --resume: {skipped} samples already complete"
        ));
    }
    let cache = PipelineCache::default();
    let t1 = Instant::now();
    let result: Result<()> = pool.install(|| {
        todo.par_iter().try_for_each_init(
            || Worker {
                cfg: &cfg,
                dir: &dir,
                staging: &staging,
                cache: &cache,
            },
            |w, s| {
                let lines = w.sample(s)?;
                part.lock()
                    .unwrap()
                    .write_all(lines.as_bytes())
                    .map_err(|e| Error::io(format!("writing {}", part_path.display()), e))?;
                let mut p = progress.lock().unwrap();
                p.set_message(s.split.name());
                p.inc(1);
                Ok(())
            },
        )
    });
    drop(progress);
    let _ = std::fs::remove_dir(&staging);
    result?;
    let secs = t1.elapsed().as_secs_f64();
    let built = todo.len();
    let rate = if secs > 0.0 { built as f64 / secs } else { 0.0 };
    eprintln!(
        "psns dataset: shard {shard}: built {built} samples ({} files), {skipped} already complete, in {secs:.2} s: {rate:.2} images/s ({:.2} s with start-up)",
        built * cfg.files(&plan[0]).len(),
        t0.elapsed().as_secs_f64()
    );
    match merge(&dir, &cfg, &plan)? {
        Merged::Written { files } => eprintln!(
            "psns dataset: {} samples complete; wrote {} ({files} files)",
            cfg.total(),
            dir.join(MANIFEST).display()
        ),
        Merged::Missing { samples, .. } => eprintln!(
            "psns dataset: {samples} of {} samples are not built yet (other shards); the last shard to finish writes manifest.csv, or run psns dataset merge {}",
            cfg.total(),
            dir.display()
        ),
    }
    Ok(())
}

/// Reads `DIR/dataset.toml` (bad input if `DIR` is not a dataset).
fn open_dataset(dir: &Path) -> Result<DatasetConfig> {
    if !dir.is_dir() {
        return Err(Error::Invalid(format!(
            "{} is not a directory",
            dir.display()
        )));
    }
    let p = dir.join(DESCRIPTION);
    let text = std::fs::read_to_string(&p).map_err(|_| {
        Error::Invalid(format!(
            "{} is not a psns dataset ({DESCRIPTION} is missing)",
            dir.display()
        ))
    })?;
    DatasetConfig::from_toml(&text, &p.display().to_string())
}

fn merge_cmd(dir: &Path) -> anyhow::Result<()> {
    let cfg = open_dataset(dir)?;
    let plan = cfg.plan()?;
    match merge(dir, &cfg, &plan)? {
        Merged::Written { files } => {
            eprintln!(
                "psns dataset merge: wrote {} ({files} files of {} samples)",
                dir.join(MANIFEST).display(),
                cfg.total()
            );
            Ok(())
        }
        Merged::Missing { samples, first } => Err(Damaged(format!(
            "{samples} of {} samples are not built yet (first: {first}); build the missing shards (or --resume) and merge again",
            cfg.total()
        ))
        .into()),
    }
}

fn verify(dir: &Path) -> anyhow::Result<()> {
    if !dir.is_dir() {
        return Err(Error::Invalid(format!("{} is not a directory", dir.display())).into());
    }
    if !dir.join(MANIFEST).exists() && !dir.join(DESCRIPTION).exists() {
        return Err(Error::Invalid(format!(
            "{} is not a psns dataset (no {DESCRIPTION}, no {MANIFEST})",
            dir.display()
        ))
        .into());
    }
    let mut problems: Vec<String> = Vec::new();
    let manifest = std::fs::read_to_string(dir.join(MANIFEST));
    let mut entries: Vec<(String, u64, u32)> = Vec::new();
    match &manifest {
        Ok(t) => {
            for line in t.lines().skip(1) {
                match parse_line(line) {
                    Some(e) => entries.push(e),
                    None => problems.push(format!("{MANIFEST}: damaged line '{line}'")),
                }
            }
        }
        Err(_) => problems.push(format!(
            "{MANIFEST}: missing (an unfinished build, or shards not merged: psns dataset merge {})",
            dir.display()
        )),
    }
    // what the description says the dataset holds
    let listed: std::collections::HashSet<&str> = entries.iter().map(|e| e.0.as_str()).collect();
    let mut expected = vec![DESCRIPTION.to_string(), LABELS.to_string()];
    match open_dataset(dir) {
        Ok(cfg) => match cfg.plan() {
            Ok(plan) => {
                for s in &plan {
                    expected.extend(cfg.files(s));
                }
            }
            Err(e) => problems.push(format!("{DESCRIPTION}: {e}")),
        },
        Err(e) => problems.push(format!("{DESCRIPTION}: damaged or missing ({e})")),
    }
    if manifest.is_ok() {
        for f in &expected {
            if !listed.contains(f.as_str()) {
                problems.push(format!("{f}: not in the manifest"));
            }
        }
    }
    let bad: Vec<String> = entries
        .par_iter()
        .filter_map(|(f, size, crc)| match size_crc(&dir.join(f)) {
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Some(format!("{f}: missing")),
            Err(e) => Some(format!("{f}: unreadable ({e})")),
            Ok((s, _)) if s != *size => {
                Some(format!("{f}: damaged (size {s} bytes, manifest {size})"))
            }
            Ok((_, c)) if c != *crc => {
                Some(format!("{f}: damaged (CRC32 {c:08x}, manifest {crc:08x})"))
            }
            Ok(_) => None,
        })
        .collect();
    problems.extend(bad);
    if problems.is_empty() {
        eprintln!(
            "psns dataset verify: {}: {} files present and intact",
            dir.display(),
            entries.len()
        );
        return Ok(());
    }
    let mut out = std::io::stdout().lock();
    for p in &problems {
        writeln!(out, "{p}")?;
    }
    Err(Damaged(format!(
        "dataset {} is not intact: {} problems (listed on stdout)",
        dir.display(),
        problems.len()
    ))
    .into())
}

fn preview(a: &PreviewArgs) -> anyhow::Result<()> {
    let cfg = open_dataset(&a.dir)?;
    if !(1..=20).contains(&a.per_split) {
        return Err(Error::range("per-split", a.per_split as f64, "1..20").into());
    }
    // tiles about 160 pixels wide; an even factor keeps one polarizer channel
    let mut factor = (cfg.width / 160).max(1);
    if factor > 1 && factor % 2 == 1 {
        factor += 1;
    }
    let mut rows = Vec::new();
    for (split, n) in cfg.split_counts() {
        let mut tiles = Vec::new();
        for k in 1..=n.min(a.per_split) {
            let p = a.dir.join(cfg.sample(split, k)?.file());
            let g = io::read_gray(&p)?;
            let img = g.image;
            let g8 = Image::from_vec(
                img.width,
                img.height,
                img.data.iter().map(|&v| v.min(255) as u8).collect(),
            );
            tiles.push(super::vis::gray_rgb(&super::vis::decimate(&g8, factor)));
        }
        let refs: Vec<&Image<[u8; 3]>> = tiles.iter().collect();
        rows.push(super::vis::hstack(&refs, 4));
    }
    let refs: Vec<&Image<[u8; 3]>> = rows.iter().collect();
    let sheet = super::vis::vstack(&refs, 4);
    let grey = Image::from_vec(
        sheet.width,
        sheet.height,
        sheet.data.iter().map(|p| p[0]).collect(),
    );
    io::write_png_gray8(&a.out, &grey)?;
    eprintln!(
        "psns dataset preview: wrote {} ({} folders, 1/{factor} scale)",
        a.out.display(),
        rows.len()
    );
    Ok(())
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

    #[test]
    fn manifest_lines_round_trip_and_cut_lines_are_ignored() {
        let l = manifest_line("NFPI/N1_1_0_0_4_5_2_400_0.1.png", 123, 0xdeadbeef);
        assert_eq!(l, "NFPI/N1_1_0_0_4_5_2_400_0.1.png,123,deadbeef\n");
        assert_eq!(
            parse_line(l.trim_end()),
            Some(("NFPI/N1_1_0_0_4_5_2_400_0.1.png".into(), 123, 0xdeadbeef))
        );
        // a line cut by a kill, the header
        assert_eq!(
            parse_line("NFPI/N1_1_0_0_4_5_2_400_0.1.png,123,deadb"),
            None
        );
        assert_eq!(parse_line("file,size,crc32"), None);
        let mut m = HashMap::new();
        read_entries(&format!("{l}{l}NFPI/N2.png,5,0000"), &mut m);
        assert_eq!(m.len(), 1);
        // a cut line glued to the next entry is not taken for an entry
        assert_eq!(
            parse_line("NFPI/N2.png,32NFPI/N3.png,3257072,abcdef12"),
            None
        );
    }
}
