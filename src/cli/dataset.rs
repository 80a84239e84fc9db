//! `psns dataset build | verify | merge | preview`: the library's dataset build and manifest
//! ([`psns::dataset`]) on the command line, and the contact sheet of a built dataset.

use super::progress::Terminal;
use super::vis;
use psns::dataset::manifest::{merge, open_dataset, verify, Merged, MANIFEST};
use psns::image::Image;
use psns::options::{DatasetCmd, PreviewArgs};
use psns::{io, Error};
use std::io::Write;
use std::path::Path;

/// The dataset is not intact (exit code 1; the damaged files were listed on stdout).
#[derive(Debug)]
pub struct Damaged(pub String);
impl std::fmt::Display for Damaged {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}
impl std::error::Error for Damaged {}

/// Runs `psns dataset ...`.
pub fn run(cmd: DatasetCmd) -> anyhow::Result<()> {
    match cmd {
        DatasetCmd::Build(a) => {
            if let Some(s) = a.run(&Terminal)? {
                eprintln!("{s}");
            }
            Ok(())
        }
        DatasetCmd::Verify(a) => verify_cmd(&a.dir),
        DatasetCmd::Merge(a) => merge_cmd(&a.dir),
        DatasetCmd::Preview(a) => preview(&a),
    }
}

fn merge_cmd(dir: &Path) -> anyhow::Result<()> {
    let cfg = open_dataset(dir)?;
    let plan = cfg.plan()?;
    match merge(dir, &plan)? {
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

fn verify_cmd(dir: &Path) -> anyhow::Result<()> {
    let r = verify(dir)?;
    if r.problems.is_empty() {
        eprintln!(
            "psns dataset verify: {}: {} files present and intact",
            dir.display(),
            r.files
        );
        return Ok(());
    }
    let mut out = std::io::stdout().lock();
    for p in &r.problems {
        writeln!(out, "{p}")?;
    }
    Err(Damaged(format!(
        "dataset {} is not intact: {} problems (listed on stdout)",
        dir.display(),
        r.problems.len()
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
            tiles.push(vis::gray_rgb(&vis::decimate(&g8, factor)));
        }
        let refs: Vec<&Image<[u8; 3]>> = tiles.iter().collect();
        rows.push(vis::hstack(&refs, 4));
    }
    let refs: Vec<&Image<[u8; 3]>> = rows.iter().collect();
    let sheet = vis::vstack(&refs, 4);
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
