//! `psns dataset`: shards equal the whole build, a killed build resumes to the
//! uninterrupted result, verify catches damage, labels reproduce the images through `psns render`,
//! bad descriptions write nothing, and the Slurm / GNU parallel recipes of docs/dataset.md work.

use crate::common;
use common::{psns, stderr};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

pub(crate) fn bin() -> &'static str {
    env!("CARGO_BIN_EXE_psns")
}

/// Six samples over three folders and all three presets, 64 x 48.
pub(crate) const TINY: &str =
    "seed = 7\nwidth = 64\nheight = 48\n[splits]\nNFPI = 2\nGNIICPI = 2\nTGNIIPI = 2\n";

/// Suns from times and places; at 85 degrees south in June the sun never rises.
const SUN_TIME: &str = "seed = 2\nwidth = 64\nheight = 48\n[splits]\nGNIIPI = 3\n[sun_time]\nstart = \"2025-03-01T00:00:00Z\"\nend = \"2025-03-31T23:59:59Z\"\nlat_deg = { min = 30, max = 50 }\nlon_deg = { values = [10, 120] }\nmin_altitude_deg = 10\n[outputs]\nraw12 = true\n";
const POLAR_NIGHT: &str = "width = 64\nheight = 48\n[splits]\nNFPI = 3\n[sun_time]\nstart = \"2025-06-10T00:00:00Z\"\nend = \"2025-06-11T00:00:00Z\"\nlat_deg = -85\n";

pub(crate) fn write_config(dir: &Path, text: &str) -> PathBuf {
    let p = dir.join("d.toml");
    std::fs::write(&p, text).unwrap();
    p
}

/// Every file and directory below `dir` (hidden ones too), with the files' bytes.
fn tree(dir: &Path) -> BTreeMap<String, Option<Vec<u8>>> {
    fn walk(root: &Path, d: &Path, out: &mut BTreeMap<String, Option<Vec<u8>>>) {
        for e in std::fs::read_dir(d).unwrap() {
            let p = e.unwrap().path();
            let rel = p.strip_prefix(root).unwrap().to_string_lossy().into_owned();
            if p.is_dir() {
                out.insert(rel + "/", None);
                walk(root, &p, out);
            } else {
                out.insert(rel, Some(std::fs::read(&p).unwrap()));
            }
        }
    }
    let mut out = BTreeMap::new();
    walk(dir, dir, &mut out);
    out
}

pub(crate) fn assert_same_tree(a: &Path, b: &Path) {
    let (ta, tb) = (tree(a), tree(b));
    let only = |x: &BTreeMap<String, Option<Vec<u8>>>, y: &BTreeMap<String, Option<Vec<u8>>>| {
        x.keys()
            .filter(|k| !y.contains_key(*k))
            .cloned()
            .collect::<Vec<_>>()
    };
    let (oa, ob) = (only(&ta, &tb), only(&tb, &ta));
    assert!(
        oa.is_empty() && ob.is_empty(),
        "only in {}: {oa:?}; only in {}: {ob:?}",
        a.display(),
        b.display()
    );
    for (k, v) in &ta {
        assert!(v == &tb[k], "{k} differs");
    }
}

pub(crate) fn build(out: &Path, config: &Path, extra: &[&str]) -> std::process::Output {
    let mut args = vec![
        "dataset",
        "build",
        "--out",
        out.to_str().unwrap(),
        "--config",
        config.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    psns(&args)
}

pub(crate) fn ok(o: &std::process::Output) {
    assert!(o.status.success(), "{:?}: {}", o.status, stderr(o));
}

/// The rows of a `labels.csv`, each a map from column name to value.
/// The options of `psns render` that make a label row's frame again: its preset, size, camera,
/// pose, sun, sky, seed and frame. An empty value (a neutral point of a model without them) or
/// `pan` (a neutral point on Pan's law, the default) is left to the default.
pub(crate) fn label_render_args<'a>(r: &BTreeMap<&str, &'a str>) -> Vec<&'a str> {
    let mut v = Vec::new();
    for (opt, col) in [
        ("--preset", "preset"),
        ("--width", "width"),
        ("--height", "height"),
        ("--yaw", "yaw_deg"),
        ("--pitch", "pitch_deg"),
        ("--roll", "roll_deg"),
        ("--frame", "frame"),
        ("--focal-length", "focal_length_mm"),
        ("--pixel-pitch", "pixel_pitch_um"),
        ("--sun-altitude", "sun_altitude_deg"),
        ("--sun-azimuth", "sun_azimuth_deg"),
        ("--turbidity", "turbidity"),
        ("--wavelength", "wavelength_nm"),
        ("--albedo", "albedo"),
        ("--seed", "seed"),
        ("--frame-index", "frame_index"),
        ("--sky-grid", "sky_grid"),
        ("--model", "model"),
        ("--radiance", "radiance"),
        ("--dop-model", "dop_model"),
        ("--babinet", "babinet"),
        ("--brewster", "brewster"),
    ] {
        let law = ["babinet", "brewster"].contains(&col) && r[col] == "pan";
        if !r[col].is_empty() && !law {
            v.extend([opt, r[col]]);
        }
    }
    v
}

pub(crate) fn label_rows(labels: &str) -> Vec<BTreeMap<&str, &str>> {
    let mut lines = labels.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    lines
        .map(|l| header.iter().copied().zip(l.split(',')).collect())
        .collect()
}
#[test]
fn shards_one_after_another_and_at_once_equal_the_whole_build() {
    let t = tempfile::tempdir().unwrap();
    let cfg = write_config(t.path(), TINY);
    let whole = t.path().join("whole");
    let o = build(&whole, &cfg, &["--jobs", "2"]);
    ok(&o);
    // progress in a log: plain lines with the rate; the summary with images/s
    let e = stderr(&o);
    assert!(e.contains("psns dataset: 6/6 images"), "{e}");
    assert!(e.contains("images/s"), "{e}");
    assert!(whole.join("manifest.csv").is_file());
    assert!(!whole.join(".parts").exists());
    let n_png = |d: &Path| std::fs::read_dir(d).unwrap().count();
    assert_eq!(n_png(&whole.join("NFPI")), 2);
    assert_eq!(n_png(&whole.join("TGNIIPI")), 2);

    // three shards one after another; the dataset is incomplete until the last one
    let sharded = t.path().join("sharded");
    ok(&build(&sharded, &cfg, &["--shard", "1/3", "--jobs", "1"]));
    ok(&build(&sharded, &cfg, &["--shard", "3/3", "--jobs", "1"]));
    assert!(!sharded.join("manifest.csv").exists());
    let v = psns(&["dataset", "verify", sharded.to_str().unwrap()]);
    assert_eq!(v.status.code(), Some(1), "{}", stderr(&v));
    assert!(String::from_utf8_lossy(&v.stdout).contains("manifest.csv: missing"));
    let m = psns(&["dataset", "merge", sharded.to_str().unwrap()]);
    assert_eq!(m.status.code(), Some(1));
    assert!(
        stderr(&m).contains("2 of 6 samples are not built yet"),
        "{}",
        stderr(&m)
    );
    ok(&build(&sharded, &cfg, &["--shard", "2/3", "--jobs", "1"]));
    assert_same_tree(&whole, &sharded);

    // three shards at the same time into one directory
    let at_once = t.path().join("at_once");
    let kids: Vec<_> = (1..=3)
        .map(|k| {
            Command::new(bin())
                .args(["dataset", "build", "--out"])
                .arg(&at_once)
                .arg("--config")
                .arg(&cfg)
                .args(["--jobs", "1", "--shard", &format!("{k}/3")])
                .stderr(Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    for k in kids {
        ok(&k.wait_with_output().unwrap());
    }
    // whichever finished last merged; merging again is harmless
    if !at_once.join("manifest.csv").exists() {
        ok(&psns(&["dataset", "merge", at_once.to_str().unwrap()]));
    }
    assert_same_tree(&whole, &at_once);
    ok(&psns(&["dataset", "verify", at_once.to_str().unwrap()]));
}

/// Kills a build part-way (SIGKILL, no chance to tidy up), checks that every image it left is
/// whole, resumes it and compares with an uninterrupted build.
#[test]
fn killed_build_resumes_to_the_uninterrupted_result() {
    let t = tempfile::tempdir().unwrap();
    let text = "seed = 3\nwidth = 128\nheight = 96\n[splits]\nNFPI = 150\nGNIIPI = 150\n[outputs]\ntruth = true\n";
    let cfg = write_config(t.path(), text);
    let reference = t.path().join("reference");
    ok(&build(&reference, &cfg, &["--jobs", "2"]));

    let out = t.path().join("killed");
    let mut child = Command::new(bin())
        .args(["dataset", "build", "--out"])
        .arg(&out)
        .arg("--config")
        .arg(&cfg)
        .args(["--jobs", "1"])
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let part = out.join(".parts/manifest-1-of-1.csv");
    let t0 = Instant::now();
    loop {
        let lines = std::fs::read_to_string(&part).map_or(0, |s| s.lines().count());
        if lines >= 30 {
            break;
        }
        assert!(
            t0.elapsed() < Duration::from_secs(20),
            "build made no progress"
        );
        std::thread::sleep(Duration::from_millis(1));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    // the samples the killed build finished: all three files (image, DOP, AOP) in its manifest
    let text = std::fs::read_to_string(&part).unwrap();
    let mut per_sample: BTreeMap<String, usize> = BTreeMap::new();
    for l in text.lines() {
        let f: Vec<&str> = l.split(',').collect();
        if f.len() == 3 && f[2].len() == 8 {
            let stem = f[0].rsplit('/').next().unwrap();
            let stem = stem.trim_end_matches(".png").trim_end_matches("_dop.npy");
            *per_sample
                .entry(stem.trim_end_matches("_aop.npy").to_string())
                .or_default() += 1;
        }
    }
    let finished = per_sample.values().filter(|&&n| n == 3).count();
    // as if the kill had cut the part's last line
    let mut f = std::fs::OpenOptions::new()
        .append(true)
        .open(&part)
        .unwrap();
    std::io::Write::write_all(&mut f, b"NFPI/N1_cut,31").unwrap();
    drop(f);
    assert!(
        !out.join("manifest.csv").exists(),
        "the build finished before it was killed: make it longer"
    );
    // whatever the kill left in the folders is whole (equal to the reference's file)
    let mut left = 0;
    for split in ["NFPI", "GNIIPI"] {
        for e in std::fs::read_dir(out.join(split)).unwrap() {
            let p = e.unwrap().path();
            let name = p.file_name().unwrap();
            let want = std::fs::read(reference.join(split).join(name)).unwrap();
            assert!(
                std::fs::read(&p).unwrap() == want,
                "{} is not whole",
                p.display()
            );
            left += 1;
        }
    }
    assert!(
        (10..300).contains(&left),
        "{left} images left by the killed build"
    );

    let o = build(&out, &cfg, &["--jobs", "2", "--resume"]);
    ok(&o);
    let e = stderr(&o);
    let skipped: usize = e
        .lines()
        .find(|l| l.ends_with("samples already complete"))
        .and_then(|l| l.split("--resume: ").nth(1))
        .and_then(|s| s.split_whitespace().next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no resume count in: {e}"));
    assert_eq!(skipped, finished, "{e}");
    assert!((10..300).contains(&skipped), "{e}");
    assert_same_tree(&reference, &out);
}

#[test]
fn resume_redoes_exactly_the_missing_and_damaged_samples() {
    let t = tempfile::tempdir().unwrap();
    let cfg = write_config(t.path(), TINY);
    let a = t.path().join("a");
    ok(&build(&a, &cfg, &["--jobs", "1"]));
    let before = tree(&a);
    let imgs: Vec<PathBuf> = std::fs::read_dir(a.join("GNIICPI"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    std::fs::remove_file(&imgs[0]).unwrap();
    let mut b = std::fs::read(&imgs[1]).unwrap();
    let k = b.len() / 2;
    b[k] ^= 0x10;
    std::fs::write(&imgs[1], b).unwrap();
    let o = build(&a, &cfg, &["--jobs", "1", "--resume"]);
    ok(&o);
    let e = stderr(&o);
    assert!(e.contains("--resume: 4 samples already complete"), "{e}");
    assert!(e.contains("built 2 samples"), "{e}");
    assert_eq!(before, tree(&a));
    // without --resume every sample of the shard is rendered again
    let o = build(&a, &cfg, &["--jobs", "1"]);
    assert!(stderr(&o).contains("built 6 samples"), "{}", stderr(&o));
    assert_eq!(before, tree(&a));
}

#[test]
fn verify_names_deleted_truncated_and_bit_flipped_files() {
    let t = tempfile::tempdir().unwrap();
    let cfg = write_config(
        t.path(),
        &format!("{TINY}[outputs]\npolarizer_images = true\n"),
    );
    let d = t.path().join("d");
    ok(&build(&d, &cfg, &["--jobs", "1"]));
    let v = psns(&["dataset", "verify", d.to_str().unwrap()]);
    ok(&v);
    assert!(
        stderr(&v).contains("32 files present and intact"),
        "{}",
        stderr(&v)
    );
    let labels = std::fs::read_to_string(d.join("labels.csv")).unwrap();
    let files: Vec<&str> = labels
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(1).unwrap())
        .collect();
    let (deleted, truncated, flipped) = (files[0], files[3], files[5]);
    std::fs::remove_file(d.join(deleted)).unwrap();
    let b = std::fs::read(d.join(truncated)).unwrap();
    std::fs::write(d.join(truncated), &b[..b.len() - 7]).unwrap();
    let mut b = std::fs::read(d.join(flipped)).unwrap();
    b[100] ^= 1;
    std::fs::write(d.join(flipped), b).unwrap();
    // one extra: a polarizer image
    let pol = format!("extras/{}_i45.png", files[2].trim_end_matches(".png"));
    std::fs::remove_file(d.join(&pol)).unwrap();
    let v = psns(&["dataset", "verify", d.to_str().unwrap()]);
    assert_eq!(v.status.code(), Some(1), "{}", stderr(&v));
    let out = String::from_utf8_lossy(&v.stdout);
    assert!(out.contains(&format!("{deleted}: missing")), "{out}");
    assert!(
        out.contains(&format!("{truncated}: damaged (size")),
        "{out}"
    );
    assert!(out.contains(&format!("{flipped}: damaged (CRC32")), "{out}");
    assert!(out.contains(&format!("{pol}: missing")), "{out}");
    assert_eq!(out.lines().count(), 4, "{out}");
    assert!(stderr(&v).contains("4 problems"), "{}", stderr(&v));
    // a damaged labels.csv is caught too
    let mut l = std::fs::read(d.join("labels.csv")).unwrap();
    l[200] ^= 4;
    std::fs::write(d.join("labels.csv"), l).unwrap();
    let v = psns(&["dataset", "verify", d.to_str().unwrap()]);
    assert!(String::from_utf8_lossy(&v.stdout).contains("labels.csv: damaged (CRC32"));
}

fn num(s: &str) -> f64 {
    s.parse()
        .unwrap_or_else(|_| panic!("'{s}' is not a number"))
}

#[test]
fn labels_match_file_names_and_rerendering_from_them_gives_the_image() {
    let t = tempfile::tempdir().unwrap();
    let cfg = write_config(
        t.path(),
        "seed = 11\nwidth = 64\nheight = 48\nframe = \"enu\"\n[splits]\nGNIIPI = 4\nGNIICPI = 4\nTNFPI = 2\n[pitch_deg]\nmin = -5\nmax = 5\n[roll_deg]\nvalues = [-2, 3]\n[focal_length_mm]\nvalues = [3.5, 4]\n[outputs]\nraw12 = true\nraw12_exposure_us = { values = [500, 2000] }\n",
    );
    let d = t.path().join("d");
    ok(&build(&d, &cfg, &["--jobs", "1"]));
    let labels = std::fs::read_to_string(d.join("labels.csv")).unwrap();
    let header: Vec<&str> = labels.lines().next().unwrap().split(',').collect();
    for want in [
        "split",
        "file",
        "yaw_deg",
        "pitch_deg",
        "roll_deg",
        "frame",
        "focal_length_mm",
        "pixel_pitch_um",
        "sun_altitude_deg",
        "sun_azimuth_deg",
        "turbidity",
        "wavelength_nm",
        "albedo",
        "seed",
        "frame_index",
        "sun_cam_x",
        "sun_cam_y",
        "sun_cam_z",
    ] {
        assert!(header.contains(&want), "no column {want}");
    }
    let rows = label_rows(&labels);
    assert_eq!(rows.len(), 10);
    let mut rendered = std::collections::BTreeSet::new();
    for r in &rows {
        // the name carries the label values
        let file = r["file"];
        let (folder, name) = file.split_once('/').unwrap();
        assert_eq!(folder, r["split"]);
        let stem = name.strip_suffix(".png").unwrap();
        let parts: Vec<&str> = stem.split('_').collect();
        let prefix = match r["split"] {
            "GNIIPI" => "G",
            "GNIICPI" => "C",
            "TNFPI" => "TN",
            s => panic!("{s}"),
        };
        assert_eq!(parts[0], format!("{prefix}{}", r["number"]));
        let keys = [
            "yaw_deg",
            "pitch_deg",
            "roll_deg",
            "focal_length_mm",
            "sun_altitude_deg",
            "turbidity",
            "wavelength_nm",
            "albedo",
        ];
        for (k, v) in keys.iter().zip(&parts[1..]) {
            assert_eq!(num(v), num(r[k]), "{k} in {name}");
            assert!(
                !(v.contains('e') || v.contains('.') && v.ends_with('0')),
                "{v}"
            );
        }
        assert!(d.join(file).is_file());
        assert_eq!(r["frame"], "enu");
        // the sun vector: its z component is the sine of the sun's angle above the image plane
        let z = num(r["sun_cam_z"]);
        let (x, y) = (num(r["sun_cam_x"]), num(r["sun_cam_y"]));
        assert!(((x * x + y * y + z * z).sqrt() - 1.0).abs() < 1e-9);
        if num(r["pitch_deg"]) == 0.0 && num(r["roll_deg"]) == 0.0 {
            let alt = num(r["sun_altitude_deg"]).to_radians();
            assert!((z - alt.sin()).abs() < 1e-9);
        }
        // render every sample again through the CLI with the label values (the build reuses
        // a sensor across samples; each render here starts from scratch)
        rendered.insert(r["split"]);
        let out = t
            .path()
            .join(format!("again_{}", r["number"].to_string() + r["split"]));
        let mut args: Vec<String> = ["render", "--raw", "--bit-depth", "8"]
            .into_iter()
            .chain(label_render_args(r))
            .map(String::from)
            .collect();
        args.push("--out".into());
        args.push(out.to_str().unwrap().into());
        let a: Vec<&str> = args.iter().map(|s| s.as_str()).collect();
        ok(&psns(&a));
        let again = std::fs::read(out.join("raw.png")).unwrap();
        assert!(
            again == std::fs::read(d.join(file)).unwrap(),
            "{file} differs from psns render"
        );
        // the 12-bit camera frame likewise, with --preset camera
        let i = args.iter().position(|s| s == "--preset").unwrap();
        args[i + 1] = "camera".into();
        let b = args.iter().position(|s| s == "--bit-depth").unwrap();
        args.drain(b..b + 2);
        let o = args.iter().position(|s| s == "--out").unwrap();
        args[o + 1] = format!("{}12", args[o + 1]);
        assert!(["500", "2000"].contains(&r["raw12_exposure_us"]), "{r:?}");
        args.push("--exposure-us".into());
        args.push(r["raw12_exposure_us"].into());
        let a: Vec<&str> = args.iter().map(|s| s.as_str()).collect();
        ok(&psns(&a));
        let again = std::fs::read(Path::new(&args[o + 1]).join("raw.png")).unwrap();
        let raw12 = d.join(format!(
            "extras/{}_raw12.png",
            file.trim_end_matches(".png")
        ));
        assert!(
            again == std::fs::read(&raw12).unwrap(),
            "{} differs",
            raw12.display()
        );
    }
    assert_eq!(rendered.len(), 3);
}

#[test]
fn bad_input_exits_2_names_the_key_and_writes_nothing() {
    let t = tempfile::tempdir().unwrap();
    let out = t.path().join("never");
    let cases: &[(&str, &[&str], &str)] = &[
        ("turbidty = 3\n", &[], "turbidty"),
        (
            "[turbidity]\nmin = 0.5\nmax = 4\n",
            &[],
            "turbidity.min = 0.5 is out of range (allowed 1.7..10)",
        ),
        (
            "[splits]\nNFPI = 2\nXFPI = 1\n",
            &[],
            "splits = XFPI is out of range (allowed NFPI, GNIIPI",
        ),
        (
            "width = 63\n",
            &[],
            "width = 63 is out of range (allowed a non-zero multiple of 4)",
        ),
        (
            "[albedo]\nvalues = [0.2, 1.5]\n",
            &[],
            "albedo.values = 1.5 is out of range (allowed 0..1)",
        ),
        ("[outputs]\ntruht = true\n", &[], "truht"),
        (
            TINY,
            &["--shard", "0/3"],
            "shard = 0/3 is out of range (allowed K/N with 1 <= K <= N",
        ),
        (TINY, &["--shard", "4/3"], "shard = 4/3 is out of range"),
        (TINY, &["--shard", "three"], "shard = three"),
        (
            TINY,
            &["--jobs", "0"],
            "jobs = 0 is out of range (allowed 1..1024)",
        ),
        (
            POLAR_NIGHT,
            &[],
            "NFPI sample 1: sun_time: the sun was below min_altitude_deg = 0",
        ),
        (
            "[outputs]\nraw12_exposure_us = 500\n",
            &[],
            "outputs.raw12_exposure_us applies to the 12-bit frame",
        ),
    ];
    for (text, extra, want) in cases {
        let cfg = write_config(t.path(), text);
        let o = build(&out, &cfg, extra);
        assert_eq!(o.status.code(), Some(2), "{text} {extra:?}: {}", stderr(&o));
        assert!(
            stderr(&o).contains(want),
            "{text} {extra:?}: {}",
            stderr(&o)
        );
        assert!(!out.exists(), "{text} {extra:?} wrote {}", out.display());
    }
    let o = psns(&[
        "dataset",
        "build",
        "--out",
        out.to_str().unwrap(),
        "--config",
        t.path().join("nope.toml").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("nope.toml does not exist"),
        "{}",
        stderr(&o)
    );
    assert!(!out.exists());
    // a directory with the user's files, or another dataset, is refused and left as it was
    let cfg = write_config(t.path(), TINY);
    let mine = t.path().join("mine");
    std::fs::create_dir(&mine).unwrap();
    std::fs::write(mine.join("notes.txt"), "keep").unwrap();
    let o = build(&mine, &cfg, &[]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("holds 'notes.txt'"), "{}", stderr(&o));
    assert_eq!(tree(&mine).len(), 1);
    let d = t.path().join("d");
    ok(&build(&d, &cfg, &["--jobs", "1"]));
    let before = tree(&d);
    let other = write_config(t.path(), &TINY.replace("seed = 7", "seed = 8"));
    let o = build(&d, &other, &["--resume"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        stderr(&o).contains("holds another dataset"),
        "{}",
        stderr(&o)
    );
    assert_eq!(before, tree(&d));
    // verify and merge of something that is not a dataset: bad input
    let o = psns(&["dataset", "verify", mine.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("is not a psns dataset"),
        "{}",
        stderr(&o)
    );
    let o = psns(&["dataset", "merge", mine.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let o = psns(&[
        "dataset",
        "verify",
        t.path().join("nothing").to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
}

/// The fenced ```bash block of docs/dataset.md that contains `marker`.
#[test]
fn preview_shows_the_first_samples_of_each_folder() {
    let t = tempfile::tempdir().unwrap();
    let cfg = write_config(t.path(), TINY);
    let d = t.path().join("d");
    ok(&build(&d, &cfg, &["--jobs", "2"]));
    let sheet = t.path().join("sheet.png");
    let o = psns(&[
        "dataset",
        "preview",
        d.to_str().unwrap(),
        "--out",
        sheet.to_str().unwrap(),
        "--per-split",
        "2",
    ]);
    ok(&o);
    let s = psns::io::read_gray(&sheet).unwrap().image;
    // three folders of two 64 x 48 tiles (64 px is below the 160 px tile: scale 1), 4 px gaps
    assert_eq!((s.width, s.height), (2 * 64 + 4, 3 * 48 + 2 * 4));
    // row 2, tile 2 is TGNIIPI sample 2
    let labels = std::fs::read_to_string(d.join("labels.csv")).unwrap();
    let file = labels
        .lines()
        .nth(6)
        .unwrap()
        .split(',')
        .nth(1)
        .unwrap()
        .to_string();
    assert!(file.starts_with("TGNIIPI/TG2_"), "{file}");
    let img = psns::io::read_gray(&d.join(&file)).unwrap().image;
    for r in 0..48 {
        for c in 0..64 {
            assert_eq!(s.get(2 * 52 + r, 68 + c), img.get(r, c), "({r}, {c})");
        }
    }
    let o = psns(&[
        "dataset",
        "preview",
        d.to_str().unwrap(),
        "--out",
        sheet.to_str().unwrap(),
        "--per-split",
        "0",
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(stderr(&o).contains("per-split = 0 is out of range (allowed 1..20)"));
}

/// Without --config: PSNS at full size. One shard of 138000 builds exactly one full-size image
/// and the whole layout and label table.
#[test]
fn default_description_is_psns_at_full_size() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path().join("psns");
    let o = psns(&[
        "dataset",
        "build",
        "--out",
        d.to_str().unwrap(),
        "--shard",
        "138000/138000",
        "--jobs",
        "2",
    ]);
    ok(&o);
    for s in ["NFPI", "GNIIPI", "GNIICPI", "TNFPI", "TGNIIPI", "TGNIICPI"] {
        assert!(d.join(s).is_dir(), "{s}");
    }
    let labels = std::fs::read_to_string(d.join("labels.csv")).unwrap();
    assert_eq!(labels.lines().count(), 138_001);
    let counts = |p: &str| labels.lines().filter(|l| l.starts_with(p)).count();
    assert_eq!(counts("NFPI,"), 40_000);
    assert_eq!(counts("TGNIICPI,"), 6_000);
    // the last sample of the dataset: TGNIICPI number 6000
    let last = labels.lines().last().unwrap();
    let file = last.split(',').nth(1).unwrap();
    assert!(file.starts_with("TGNIICPI/TC6000_"), "{file}");
    let img = psns::io::read_gray(&d.join(file)).unwrap();
    assert_eq!(
        (img.image.width, img.image.height, img.bits),
        (2448, 2048, 8)
    );
    assert!(
        stderr(&o).contains("137999 of 138000 samples are not built yet"),
        "{}",
        stderr(&o)
    );
}

#[test]
fn sun_from_times_and_places_is_labelled_and_reproducible() {
    let t = tempfile::tempdir().unwrap();
    let cfg = write_config(t.path(), SUN_TIME);
    let d = t.path().join("d");
    ok(&build(&d, &cfg, &["--jobs", "1"]));
    let labels = std::fs::read_to_string(d.join("labels.csv")).unwrap();
    let rows = label_rows(&labels);
    assert_eq!(rows.len(), 3);
    for r in &rows {
        assert!(r["time_utc"].starts_with("2025-03-"), "{r:?}");
        assert!((30.0..=50.0).contains(&num(r["lat_deg"])));
        assert!(["10", "120"].contains(&r["lon_deg"]));
        assert!(num(r["sun_altitude_deg"]) >= 10.0);
        // psns sun gives the label's sun for the label's time and place (to the 0.001 deg rounding)
        let o = psns(&[
            "sun",
            "--time",
            r["time_utc"],
            "--lat",
            r["lat_deg"],
            "--lon",
            r["lon_deg"],
        ]);
        ok(&o);
        let out = String::from_utf8_lossy(&o.stdout);
        let vals: Vec<f64> = out.lines().last().unwrap().split(',').map(num).collect();
        assert!(
            (90.0 - vals[0] - num(r["sun_altitude_deg"])).abs() <= 0.0005,
            "{out} {r:?}"
        );
        assert!(
            (vals[1] - num(r["sun_azimuth_deg"])).abs() <= 0.0005,
            "{out} {r:?}"
        );
    }
    // the first sample again through psns render with the label's sun
    let r = &rows[0];
    let out = t.path().join("again");
    ok(&psns(&[
        "render",
        "--raw",
        "--preset",
        "gniipi",
        "--bit-depth",
        "8",
        "--width",
        "64",
        "--height",
        "48",
        "--yaw",
        r["yaw_deg"],
        "--pitch",
        r["pitch_deg"],
        "--roll",
        r["roll_deg"],
        "--frame",
        r["frame"],
        "--focal-length",
        r["focal_length_mm"],
        "--sun-altitude",
        r["sun_altitude_deg"],
        "--sun-azimuth",
        r["sun_azimuth_deg"],
        "--turbidity",
        r["turbidity"],
        "--wavelength",
        r["wavelength_nm"],
        "--albedo",
        r["albedo"],
        "--seed",
        r["seed"],
        "--frame-index",
        r["frame_index"],
        "--out",
        out.to_str().unwrap(),
    ]));
    assert!(
        std::fs::read(out.join("raw.png")).unwrap() == std::fs::read(d.join(r["file"])).unwrap()
    );
}

#[test]
fn polarizer_images_are_the_mosaic_channels_and_truth_has_the_frame_size() {
    let t = tempfile::tempdir().unwrap();
    let cfg = write_config(
        t.path(),
        &format!("{TINY}[outputs]\npolarizer_images = true\ntruth = true\n"),
    );
    let d = t.path().join("d");
    ok(&build(&d, &cfg, &["--jobs", "2"]));
    let labels = std::fs::read_to_string(d.join("labels.csv")).unwrap();
    for line in labels.lines().skip(1) {
        let file = line.split(',').nth(1).unwrap();
        let stem = file.trim_end_matches(".png");
        let m = psns::io::read_gray(&d.join(file)).unwrap().image;
        // IMX250MZR superpixel: (0,0) 90, (0,1) 45, (1,0) 135, (1,1) 0 degrees
        for (angle, r0, c0) in [(90, 0, 0), (45, 0, 1), (135, 1, 0), (0, 1, 1)] {
            let p = d.join(format!("extras/{stem}_i{angle}.png"));
            let img = psns::io::read_gray(&p).unwrap().image;
            assert_eq!((img.width, img.height), (32, 24));
            for r in 0..24 {
                for c in 0..32 {
                    assert_eq!(
                        img.get(r, c),
                        m.get(2 * r + r0, 2 * c + c0),
                        "{angle} ({r},{c})"
                    );
                }
            }
        }
        let dop = psns::io::read_npy_f32(&d.join(format!("extras/{stem}_dop.npy"))).unwrap();
        let aop = psns::io::read_npy_f32(&d.join(format!("extras/{stem}_aop.npy"))).unwrap();
        assert_eq!(
            (dop.width, dop.height, aop.width, aop.height),
            (64, 48, 64, 48)
        );
        assert!(dop.data.iter().all(|v| (0.0..=1.0).contains(v)), "{stem}");
        assert!(aop.data.iter().any(|&v| v != 0.0), "{stem}");
    }
}

/// On a terminal the build shows an indicatif bar with the rate and the ETA (run under `script`
/// for a pseudo-terminal; a visible skip where util-linux `script` is missing).
#[test]
fn terminal_gets_a_progress_bar_with_rate_and_eta() {
    if Command::new("script").arg("--version").output().is_err() {
        common::missing(
            "terminal_gets_a_progress_bar_with_rate_and_eta",
            "`script` (util-linux) is not installed",
        );
        return;
    }
    let t = tempfile::tempdir().unwrap();
    let cfg = write_config(t.path(), TINY);
    let d = t.path().join("d");
    let cmd = format!(
        "{} dataset build --out {} --config {} --jobs 1",
        bin(),
        d.display(),
        cfg.display()
    );
    let o = Command::new("script")
        .args(["-qec", &cmd, "/dev/null"])
        .env_remove("PSNS_PROGRESS")
        .output()
        .unwrap();
    assert!(o.status.success(), "{o:?}");
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(out.contains("psns dataset: ["), "{out}");
    assert!(out.contains(" images/s, eta "), "{out}");
    assert!(out.contains("built 6 samples"), "{out}");
    assert!(d.join("manifest.csv").is_file());
}

/// `soft_clouds = p`: about a fraction p of the samples have clouds, every sample has a camera
/// seed of its own (so the clouds differ), and `psns render --seed S --clouds` reproduces them.
#[test]
fn soft_clouds_differ_per_sample_and_render_again() {
    let t = tempfile::tempdir().unwrap();
    let cfg = write_config(
        t.path(),
        "seed = 4\nwidth = 64\nheight = 48\nsoft_clouds = 0.5\n[splits]\nGNIIPI = 8\n",
    );
    let d = t.path().join("d");
    ok(&build(&d, &cfg, &["--jobs", "1"]));
    let labels = std::fs::read_to_string(d.join("labels.csv")).unwrap();
    let rows = label_rows(&labels);
    let clouded = rows.iter().filter(|r| r["soft_clouds"] == "1").count();
    assert!((1..8).contains(&clouded), "{clouded} of 8 with clouds");
    let seeds: std::collections::BTreeSet<&str> = rows.iter().map(|r| r["seed"]).collect();
    assert_eq!(seeds.len(), 8);
    for r in &rows {
        let out = t.path().join(format!("again{}", r["number"]));
        let mut args = vec!["render", "--raw"];
        args.extend(label_render_args(r));
        args.push("--out");
        let o = out.to_str().unwrap().to_string();
        args.push(&o);
        if r["soft_clouds"] == "1" {
            args.push("--clouds");
        }
        ok(&psns(&args));
        assert!(
            std::fs::read(out.join("raw.png")).unwrap()
                == std::fs::read(d.join(r["file"])).unwrap(),
            "{}",
            r["file"]
        );
    }
}

/// A build whose 12-bit frames are overexposed says so in its summary; a well exposed one does
/// not.
#[test]
fn summary_warns_of_saturated_samples() {
    let dir = tempfile::tempdir().unwrap();
    let cfg = |us: &str| {
        format!(
            "seed = 3\nwidth = 64\nheight = 48\n[splits]\nNFPI = 2\n[outputs]\nraw12 = true\nraw12_exposure_us = {us}\n"
        )
    };
    let over = write_config(dir.path(), &cfg("5000000"));
    let o = build(&dir.path().join("over"), &over, &[]);
    ok(&o);
    let err = stderr(&o);
    let line = err
        .lines()
        .find(|l| l.contains("saturated"))
        .unwrap_or_else(|| panic!("no saturation warning: {err}"));
    assert!(line.contains("2 of 2 samples"), "{line}");
    let fine = write_config(dir.path(), &cfg("100"));
    let o = build(&dir.path().join("fine"), &fine, &[]);
    ok(&o);
    assert!(!stderr(&o).contains("saturated"), "{}", stderr(&o));
}
