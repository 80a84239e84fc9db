//! Output directories that appear whole or not at all.
//!
//! A run writes into a hidden sibling `.NAME.tmp-PID` of its `--out NAME`; only when every file is
//! written is that directory put in place of `NAME` (one `rename`, or on Linux an atomic exchange
//! with a previous run's directory, which is then removed). A run that fails, or is killed, leaves
//! `NAME` as it was; the hidden directory of a killed run is removed by the next run into the same
//! place. `NAME` may be new, empty, or hold a previous psns run's files; a directory holding other
//! files is refused before any work, so a run never deletes a user's files.

use psns::{Error, Result};
use std::path::{Path, PathBuf};

/// Files `psns render` (and `render --raw`) leaves in its output directory.
pub const RENDER_FILES: &[&str] = &[
    "li.npy",
    "dop.npy",
    "aop.npy",
    "class.npy",
    "li.png",
    "dop.png",
    "aop.png",
    "i0.png",
    "i45.png",
    "i90.png",
    "i135.png",
    "i0_16bit.png",
    "i45_16bit.png",
    "i90_16bit.png",
    "i135_16bit.png",
    "scene.json",
    "raw.png",
    "raw.tiff",
    "raw.bin",
    "raw_view.png",
    "truth_s0.npy",
    "truth_s1.npy",
    "truth_s2.npy",
    "truth_dolp.npy",
    "truth_aolp.npy",
];

/// Files `psns demosaic` leaves in its output directory.
pub const DEMOSAIC_FILES: &[&str] = &[
    "s0.npy",
    "s1.npy",
    "s2.npy",
    "dolp.npy",
    "aolp.npy",
    "dolp_debiased.npy",
    "s0.png",
    "dolp.png",
    "aolp.png",
    "aolp_dolp.png",
    "demosaic.json",
];

/// An output directory being written: files go into [`OutDir::path`], and [`OutDir::commit`]
/// puts them in place. Dropped without a commit, it removes what was written.
#[derive(Debug)]
pub struct OutDir {
    target: PathBuf,
    tmp: PathBuf,
    committed: bool,
}

/// True when the process `pid` no longer runs (Linux `/proc`; elsewhere never, so nothing of
/// another run is removed).
pub(crate) fn dead(pid: u32) -> bool {
    Path::new("/proc/self").exists() && !Path::new(&format!("/proc/{pid}")).exists()
}

/// The PID of a hidden temporary `.{base}.tmp-PID` or `.{base}.old-PID`.
pub(crate) fn temp_pid(name: &str, base: &str) -> Option<u32> {
    let rest = name.strip_prefix('.')?.strip_prefix(base)?;
    let pid = rest
        .strip_prefix(".tmp-")
        .or_else(|| rest.strip_prefix(".old-"))?;
    pid.parse().ok()
}

impl OutDir {
    /// Prepares `dir` for a run: checks it can be replaced (it holds nothing but `known`, the
    /// files of an earlier run of the same command), removes temporaries of killed runs and
    /// creates the hidden directory the run writes into.
    pub fn begin(dir: &Path, known: &[&str]) -> Result<OutDir> {
        let bad = |m: String| Error::Invalid(format!("--out {}: {m}", dir.display()));
        if dir.exists() && !dir.is_dir() {
            return Err(bad("exists and is not a directory".into()));
        }
        let abs = std::path::absolute(dir).map_err(|e| Error::input(dir, e))?;
        // `a/b/..` or `.`: name the directory itself, not its path spelling
        let abs = if dir.exists() {
            abs.canonicalize().map_err(|e| Error::input(dir, e))?
        } else {
            abs
        };
        let (parent, name) = match (abs.parent(), abs.file_name()) {
            (Some(p), Some(n)) => (p.to_path_buf(), n.to_string_lossy().into_owned()),
            _ => return Err(bad("cannot be replaced (give a directory below it)".into())),
        };
        if abs.is_dir() {
            let entries = std::fs::read_dir(&abs).map_err(|e| Error::input(dir, e))?;
            for e in entries.flatten() {
                let n = e.file_name().to_string_lossy().into_owned();
                let ours = known.contains(&n.as_str()) && e.path().is_file();
                // a hidden `.FILE.tmp-PID` of a killed run that wrote file by file
                let stale = n.starts_with('.')
                    && n.rsplit_once(".tmp-")
                        .is_some_and(|(_, p)| p.parse::<u32>().is_ok());
                if !ours && !stale {
                    return Err(bad(format!(
                        "holds '{n}', which this command does not write; give a new or empty directory (a run replaces its directory whole)"
                    )));
                }
            }
        }
        std::fs::create_dir_all(&parent)
            .map_err(|e| Error::io(format!("creating {}", parent.display()), e))?;
        if let Ok(entries) = std::fs::read_dir(&parent) {
            for e in entries.flatten() {
                let n = e.file_name().to_string_lossy().into_owned();
                if temp_pid(&n, &name).is_some_and(dead) {
                    let _ = std::fs::remove_dir_all(e.path());
                }
            }
        }
        let tmp = parent.join(format!(".{name}.tmp-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&tmp);
        std::fs::create_dir(&tmp)
            .map_err(|e| Error::io(format!("creating {}", tmp.display()), e))?;
        Ok(OutDir {
            target: abs,
            tmp,
            committed: false,
        })
    }

    /// Where the run writes its files.
    pub fn path(&self) -> &Path {
        &self.tmp
    }

    /// Puts the written directory in place of the target, replacing a previous run's directory.
    pub fn commit(mut self) -> Result<()> {
        let ctx = || format!("putting {} in place", self.target.display());
        if !self.target.exists() {
            std::fs::rename(&self.tmp, &self.target).map_err(|e| Error::io(ctx(), e))?;
        } else {
            exchange(&self.tmp, &self.target).map_err(|e| Error::io(ctx(), e))?;
            // `tmp` now holds the previous run's files
            let _ = std::fs::remove_dir_all(&self.tmp);
        }
        self.committed = true;
        Ok(())
    }
}

impl Drop for OutDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.tmp);
        }
    }
}

/// Swaps two directories: atomically on Linux (`renameat2` with `RENAME_EXCHANGE`); elsewhere,
/// or where the file system lacks it, by two renames (the target is missing for an instant, and
/// a crash there leaves both directories under their hidden names).
fn exchange(new: &Path, target: &Path) -> std::io::Result<()> {
    #[cfg(target_os = "linux")]
    {
        use std::ffi::CString;
        use std::os::unix::ffi::OsStrExt;
        let a = CString::new(new.as_os_str().as_bytes())?;
        let b = CString::new(target.as_os_str().as_bytes())?;
        // SAFETY: two valid NUL-terminated paths; the call only renames.
        let r = unsafe {
            libc::renameat2(
                libc::AT_FDCWD,
                a.as_ptr(),
                libc::AT_FDCWD,
                b.as_ptr(),
                libc::RENAME_EXCHANGE,
            )
        };
        if r == 0 {
            return Ok(());
        }
        let e = std::io::Error::last_os_error();
        if !matches!(e.raw_os_error(), Some(libc::EINVAL) | Some(libc::ENOSYS)) {
            return Err(e);
        }
    }
    let old = new.with_file_name(
        new.file_name()
            .unwrap_or_default()
            .to_string_lossy()
            .replacen(".tmp-", ".old-", 1),
    );
    std::fs::rename(target, &old)?;
    std::fs::rename(new, target)?;
    std::fs::rename(&old, new)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(d: &Path) -> Vec<String> {
        let mut v: Vec<String> = std::fs::read_dir(d)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        v
    }

    #[test]
    fn a_run_replaces_its_directory_whole_or_not_at_all() {
        let root = tempfile::tempdir().unwrap();
        let out = root.path().join("o");
        // first run: new directory
        let w = OutDir::begin(&out, RENDER_FILES).unwrap();
        std::fs::write(w.path().join("li.npy"), "old").unwrap();
        std::fs::write(w.path().join("raw.png"), "old").unwrap();
        w.commit().unwrap();
        assert_eq!(names(&out), ["li.npy", "raw.png"]);
        // a failed run leaves the directory as it was and no temporaries
        let w = OutDir::begin(&out, RENDER_FILES).unwrap();
        std::fs::write(w.path().join("li.npy"), "new").unwrap();
        drop(w);
        assert_eq!(std::fs::read_to_string(out.join("li.npy")).unwrap(), "old");
        assert_eq!(names(root.path()), ["o"]);
        // a run that finishes replaces every file, also those it did not write again
        let w = OutDir::begin(&out, RENDER_FILES).unwrap();
        std::fs::write(w.path().join("li.npy"), "new").unwrap();
        w.commit().unwrap();
        assert_eq!(names(&out), ["li.npy"]);
        assert_eq!(std::fs::read_to_string(out.join("li.npy")).unwrap(), "new");
        assert_eq!(names(root.path()), ["o"]);
    }

    #[test]
    fn stale_temporaries_are_removed_and_foreign_files_refused() {
        let root = tempfile::tempdir().unwrap();
        let out = root.path().join("o");
        std::fs::create_dir(&out).unwrap();
        // a killed run's hidden directory (PID 4294967295 never runs) and a killed file write
        std::fs::create_dir(root.path().join(".o.tmp-4294967295")).unwrap();
        std::fs::write(out.join(".li.npy.tmp-4294967295"), "x").unwrap();
        let w = OutDir::begin(&out, RENDER_FILES).unwrap();
        w.commit().unwrap();
        assert_eq!(names(root.path()), ["o"]);
        assert!(names(&out).is_empty());
        // the user's own file: refused before any work, and kept
        std::fs::write(out.join("notes.txt"), "mine").unwrap();
        let e = OutDir::begin(&out, RENDER_FILES).unwrap_err();
        assert!(e.is_usage() && e.to_string().contains("notes.txt"), "{e}");
        assert_eq!(names(&out), ["notes.txt"]);
        // another command's output is not replaced either
        std::fs::remove_file(out.join("notes.txt")).unwrap();
        std::fs::write(out.join("raw.png"), "render's").unwrap();
        let e = OutDir::begin(&out, DEMOSAIC_FILES).unwrap_err();
        assert!(e.to_string().contains("raw.png"), "{e}");
        std::fs::write(out.join("notes.txt"), "mine").unwrap();
        // a file where the directory should be
        let e = OutDir::begin(&out.join("notes.txt"), RENDER_FILES).unwrap_err();
        assert!(e.to_string().contains("not a directory"), "{e}");
    }
}
