//! A dataset's manifest: `file,size,crc32` lines (CRC in 8 hex digits) for every file, written by
//! the build into per-shard parts (`.parts/manifest-K-of-N.csv`, one line per finished file) and
//! merged into `manifest.csv` when every sample is present; and the check of a dataset against it.

use super::{DatasetConfig, Plan};
use crate::{Error, Result};
use rayon::prelude::*;
use std::collections::HashMap;
use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

/// The description in force.
pub const DESCRIPTION: &str = "dataset.toml";
/// One label row per sample.
pub const LABELS: &str = "labels.csv";
/// Size and CRC32 of every file.
pub const MANIFEST: &str = "manifest.csv";
/// Manifest parts and staging directories while a build runs.
pub const PARTS: &str = ".parts";
/// The optional outputs.
pub const EXTRAS: &str = "extras";

/// Writes a file every shard writes with the same content (atomically), unless it is already
/// there with that content: shards starting or finishing together then rarely write at once.
pub(crate) fn write_shared(path: &Path, text: &str) -> Result<()> {
    write_shared_with(path, |w| {
        w.write_all(text.as_bytes())
            .map_err(|e| Error::io(format!("writing {}", path.display()), e))?;
        Ok(true)
    })
    .map(|_| ())
}

/// [`write_shared`] for content written piece by piece by `body` (into a temporary file next to
/// `path`, compared with the file already there as it goes): the content is never held whole.
/// `Ok(false)` if `body` declined (returned `Ok(false)`): nothing is written then.
pub(crate) fn write_shared_with(
    path: &Path,
    body: impl FnOnce(&mut dyn Write) -> Result<bool>,
) -> Result<bool> {
    let name = path.file_name().map(|n| n.to_string_lossy().into_owned());
    let name = name.unwrap_or_default();
    // the temporary name of io::write_atomic, which remove_stale_staging knows
    let tmp = path.with_file_name(format!(".{name}.tmp-{}", std::process::id()));
    let ctx = || format!("writing {}", path.display());
    let result = (|| {
        let f = File::create(&tmp).map_err(|e| Error::io(ctx(), e))?;
        let mut w = Tee {
            out: BufWriter::with_capacity(1 << 20, f),
            old: File::open(path)
                .ok()
                .map(|f| BufReader::with_capacity(1 << 20, f)),
            buf: Vec::new(),
        };
        if !body(&mut w)? {
            return Ok(None);
        }
        w.out.flush().map_err(|e| Error::io(ctx(), e))?;
        // the same content only if the old file ends here too
        let same = w
            .old
            .as_mut()
            .is_some_and(|r| r.read(&mut [0u8]).is_ok_and(|n| n == 0));
        Ok(Some(same))
    })();
    match result {
        Ok(Some(false)) => std::fs::rename(&tmp, path)
            .map(|_| true)
            .map_err(|e| Error::io(ctx(), e)),
        other => {
            let _ = std::fs::remove_file(&tmp);
            other.map(|w| w.is_some())
        }
    }
}

/// Writes into `out` and compares with `old` (dropped at the first difference).
struct Tee {
    out: BufWriter<File>,
    old: Option<BufReader<File>>,
    buf: Vec<u8>,
}

impl Write for Tee {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        self.out.write_all(b)?;
        if let Some(r) = &mut self.old {
            self.buf.resize(b.len(), 0);
            if r.read_exact(&mut self.buf).is_err() || self.buf != b {
                self.old = None;
            }
        }
        Ok(b.len())
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.out.flush()
    }
}

/// Size and CRC32 of a file.
pub(crate) fn size_crc(path: &Path) -> std::io::Result<(u64, u32)> {
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
pub(crate) fn manifest_line(file: &str, size: u64, crc: u32) -> String {
    format!("{file},{size},{crc:08x}\n")
}

/// One manifest line `file,size,crc32` (8 hex digits), or `None` (the header, a line cut by a
/// kill, damage).
pub(crate) fn parse_line(line: &str) -> Option<(String, u64, u32)> {
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
pub(crate) fn read_entries(text: &str, into: &mut HashMap<String, (u64, u32)>) {
    for (f, size, crc) in text.lines().filter_map(parse_line) {
        into.insert(f, (size, crc));
    }
}

/// Every entry known in `dir`: `manifest.csv` and then every part (a later entry wins). Also
/// returns the part files read.
pub(crate) fn known_entries(dir: &Path) -> (HashMap<String, (u64, u32)>, Vec<PathBuf>) {
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
pub(crate) fn complete(dir: &Path, files: &[String], known: &HashMap<String, (u64, u32)>) -> bool {
    files.iter().all(|f| match known.get(f) {
        Some(&want) => size_crc(&dir.join(f)).is_ok_and(|got| got == want),
        None => false,
    })
}

/// How a merge went.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Merged {
    /// `manifest.csv` is written, listing this many files.
    Written {
        /// Files listed.
        files: usize,
    },
    /// Samples are missing (other shards still to build).
    Missing {
        /// Samples without every file.
        samples: u64,
        /// The first file of the first missing sample.
        first: String,
    },
}

/// Writes `manifest.csv` when every file of every sample has an entry; then removes `.parts`.
/// The manifest is written as the plan is walked (and dropped at the first missing file), so
/// its text is never held whole.
pub fn merge(dir: &Path, plan: &Plan) -> Result<Merged> {
    let cfg = plan.config();
    let (known, parts) = known_entries(dir);
    let path = dir.join(MANIFEST);
    let ctx = || format!("writing {}", path.display());
    let (mut missing, mut first) = (0u64, String::new());
    let mut files = 2;
    let written = write_shared_with(&path, |w| {
        w.write_all(b"file,size,crc32\n")
            .map_err(|e| Error::io(ctx(), e))?;
        for name in [DESCRIPTION, LABELS] {
            let p = dir.join(name);
            let (size, crc) =
                size_crc(&p).map_err(|e| Error::io(format!("reading {}", p.display()), e))?;
            w.write_all(manifest_line(name, size, crc).as_bytes())
                .map_err(|e| Error::io(ctx(), e))?;
        }
        plan.walk(
            |s| cfg.files(&s),
            |fs| {
                let mut whole = true;
                for f in &fs {
                    match known.get(f) {
                        Some(&(size, crc)) if missing == 0 => w
                            .write_all(manifest_line(f, size, crc).as_bytes())
                            .map_err(|e| Error::io(ctx(), e))?,
                        Some(_) => {}
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
                Ok(())
            },
        )?;
        Ok(missing == 0)
    })?;
    if !written {
        return Ok(Merged::Missing {
            samples: missing,
            first,
        });
    }
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

/// Reads `DIR/dataset.toml` (bad input if `DIR` is not a dataset).
pub fn open_dataset(dir: &Path) -> Result<DatasetConfig> {
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

/// What [`verify`] found: the files the manifest lists, and every problem (missing, damaged,
/// unlisted files, a damaged manifest or description), one line each.
#[derive(Clone, Debug, Default)]
pub struct VerifyReport {
    /// Files the manifest lists.
    pub files: usize,
    /// Problems, one line each; none for an intact dataset.
    pub problems: Vec<String>,
}

/// Checks every file of the dataset in `dir` against its manifest and description.
pub fn verify(dir: &Path) -> Result<VerifyReport> {
    if !dir.is_dir() {
        return Err(Error::Invalid(format!(
            "{} is not a directory",
            dir.display()
        )));
    }
    if !dir.join(MANIFEST).exists() && !dir.join(DESCRIPTION).exists() {
        return Err(Error::Invalid(format!(
            "{} is not a psns dataset (no {DESCRIPTION}, no {MANIFEST})",
            dir.display()
        )));
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
    let mut unlisted = Vec::new();
    let mut expect = |f: &str| {
        if manifest.is_ok() && !listed.contains(f) {
            unlisted.push(format!("{f}: not in the manifest"));
        }
    };
    expect(DESCRIPTION);
    expect(LABELS);
    match open_dataset(dir) {
        Ok(cfg) => match cfg.plan() {
            Ok(plan) => plan.walk(
                |s| cfg.files(&s),
                |fs| {
                    fs.iter().for_each(|f| expect(f));
                    Ok(())
                },
            )?,
            Err(e) => problems.push(format!("{DESCRIPTION}: {e}")),
        },
        Err(e) => problems.push(format!("{DESCRIPTION}: damaged or missing ({e})")),
    }
    problems.extend(unlisted);
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
    Ok(VerifyReport {
        files: entries.len(),
        problems,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

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
