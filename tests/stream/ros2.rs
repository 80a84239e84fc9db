//! ROS 2 bags from `psns stream --format rosbag2|mcap` and `psns convert`, read by two readers
//! nobody here wrote (rosbags' AnyReader with the Humble type store, and mcap with
//! mcap-ros2-support's DecoderFactory, from the test venv: `tests/stream/ros2_check.py`): topics, types,
//! counts, every field against the psns stream of the same options; psns's CDR against rosbags'
//! `serialize_cdr`; conversion equal to the direct bag; bad input and full disks.

use crate::common;
use common::{psns, psns_stdin, python_cmd, stderr};
use psns::camera::{Intrinsics, Projection};
use psns::ros2::msg::{
    Float64MultiArray, Header, Image, Message, PoseStamped, TfMessage, TransformStamped,
    Vector3Stamped,
};
use psns::ros2::{self, FrameId, ImageEncoding, Time};
use serde_json::json;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Small frames: the checks are about the bag, not the picture.
const SMALL: [&str; 4] = ["--width", "96", "--height", "64"];

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

fn checker() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/stream/ros2_check.py")
}

/// Fails (never skips) when the venv lacks the readers.
fn require_readers() {
    let o = python_cmd()
        .args([
            "-c",
            "import numpy, rosbags.highlevel, mcap.reader, mcap_ros2.decoder",
        ])
        .output();
    let ok = o.as_ref().is_ok_and(|o| o.status.success());
    assert!(
        ok,
        "these tests read bags with rosbags, mcap and mcap-ros2-support: run them with tools/test \
         (it installs tools/requirements-test.txt into .venv), or point PSNS_PYTHON at a Python \
         that has them ({:?})",
        o.map(|o| String::from_utf8_lossy(&o.stderr).into_owned())
    );
}

/// Runs the checker; returns its stdout, failing with its stderr.
fn check(args: &[&str]) -> String {
    require_readers();
    let o = python_cmd().arg(checker()).args(args).output().unwrap();
    assert!(
        o.status.success(),
        "ros2_check.py {args:?} failed:\n{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8(o.stdout).unwrap()
}

/// `psns stream` with `args`, asserting success.
fn stream(args: &[&str]) {
    let o = psns(&[&["stream"], args].concat());
    assert!(o.status.success(), "psns stream {args:?}: {}", stderr(&o));
}

/// A trajectory with a place, so the sun moves (SPA per frame) and the pose turns.
fn trajectory(dir: &Path) -> PathBuf {
    let p = dir.join("traj.csv");
    std::fs::write(
        &p,
        "t_s,yaw_deg,pitch_deg,roll_deg,lat_deg,lon_deg,height_m\n\
         0,10,5,-3,48.1,11.6,520\n\
         0.25,40,12.5,4,48.1,11.6,520\n\
         1.5,-170,30,0,48.2,11.7,530\n\
         3600.125,95,-20,60,48.2,11.7,530\n",
    )
    .unwrap();
    p
}

fn hdr(sec: i32, nanosec: u32, frame_id: FrameId) -> serde_json::Value {
    json!({"sec": sec, "nanosec": nanosec, "frame_id": frame_id.as_str()})
}

#[test]
fn cdr_of_every_message_equals_rosbags_serialize_cdr() {
    let d = tempfile::tempdir().unwrap();
    let t = Time {
        sec: 1_750_500_000,
        nanosec: 123_456_789,
    };
    let h = |frame_id| Header { stamp: t, frame_id };
    let mut cases: Vec<(serde_json::Value, Vec<u8>, &str)> = Vec::new();
    // Time alone, with a negative second (int32) and the largest nanosecond
    let neg = Time {
        sec: -7,
        nanosec: 999_999_999,
    };
    cases.push((
        json!({"kind": "time", "value": {"sec": -7, "nanosec": 999_999_999}}),
        neg.to_cdr().unwrap(),
        Time::SCHEMA,
    ));
    for f in [FrameId::Enu, FrameId::CameraOptical] {
        cases.push((
            json!({"kind": "header", "value": hdr(t.sec, t.nanosec, f)}),
            h(f).to_cdr().unwrap(),
            Header::SCHEMA,
        ));
    }
    // images whose data end off the 4-byte grid, in each encoding
    let px: Vec<u8> = (0..24u8).map(|i| i.wrapping_mul(37)).collect();
    for (enc, w, hgt) in [
        (ImageEncoding::Mono8, 3u32, 1u32),
        (ImageEncoding::Mono8, 5, 3),
        (ImageEncoding::Mono16, 3, 2),
        (ImageEncoding::Float32, 2, 3),
    ] {
        let n = (w * hgt * enc.bytes_per_pixel()) as usize;
        let im = Image::new(h(FrameId::CameraOptical), w, hgt, enc, &px[..n]).unwrap();
        cases.push((
            json!({"kind": "image", "value": {
                "header": hdr(t.sec, t.nanosec, FrameId::CameraOptical),
                "height": hgt, "width": w, "encoding": enc.as_str(), "step": im.step(),
                "data": &px[..n]}}),
            im.to_cdr().unwrap(),
            Image::SCHEMA,
        ));
    }
    // camera infos: the pinhole (plumb_bob, 5 zeros) and a fitted fisheye (equidistant, 4)
    for (proj, fl) in [
        (Projection::Rectilinear, 4.0),
        (Projection::Stereographic, 1.8),
        (Projection::Equidistant, 1.8),
    ] {
        let intr = Intrinsics {
            width: 2448,
            height: 2047,
            focal_length_mm: fl,
            pixel_pitch_um: 3.45,
            principal_point: Some([1223.25, 1020.125]),
            projection: proj,
            lens: None,
        };
        let ci = ros2::camera_info(h(FrameId::CameraOptical), &intr).unwrap();
        cases.push((
            json!({"kind": "camera_info", "value": {
                "header": hdr(t.sec, t.nanosec, FrameId::CameraOptical),
                "height": ci.height, "width": ci.width,
                "distortion_model": ci.distortion_model.as_str(), "d": ci.d,
                "k": ci.k, "r": ci.r, "p": ci.p}}),
            ci.to_cdr().unwrap(),
            psns::ros2::msg::CameraInfo::SCHEMA,
        ));
    }
    let q = [0.25f64.sqrt(), -0.5, 0.5, -(0.25f64.sqrt())];
    let pose = PoseStamped {
        header: h(FrameId::Enu),
        position: [1.5, -2.25, 1e-300],
        orientation_xyzw: q,
    };
    cases.push((
        json!({"kind": "pose", "value": {"header": hdr(t.sec, t.nanosec, FrameId::Enu),
            "position": pose.position, "orientation_xyzw": q}}),
        pose.to_cdr().unwrap(),
        PoseStamped::SCHEMA,
    ));
    let v = Vector3Stamped {
        header: h(FrameId::Enu),
        vector: [0.1, -0.7, 0.704_321_987_654_321],
    };
    cases.push((
        json!({"kind": "vector3", "value": {"header": hdr(t.sec, t.nanosec, FrameId::Enu),
            "vector": v.vector}}),
        v.to_cdr().unwrap(),
        Vector3Stamped::SCHEMA,
    ));
    // transforms: none, and two (the padding before each translation differs with the
    // child frame id's length)
    let tf_of = |tfs: &[TransformStamped]| {
        let ts: Vec<_> = tfs
            .iter()
            .map(|t| {
                json!({"header": hdr(t.header.stamp.sec, t.header.stamp.nanosec, t.header.frame_id),
                    "child_frame_id": t.child_frame_id.as_str(),
                    "translation": t.translation, "rotation_xyzw": t.rotation_xyzw})
            })
            .collect();
        json!({"kind": "tf", "value": {"transforms": ts}})
    };
    let two = [
        TransformStamped {
            header: h(FrameId::Enu),
            child_frame_id: FrameId::CameraOptical,
            translation: [0.0; 3],
            rotation_xyzw: q,
        },
        TransformStamped {
            header: h(FrameId::CameraOptical),
            child_frame_id: FrameId::Enu,
            translation: [1.0, -2.5, 3e-7],
            rotation_xyzw: [0.0, 0.0, 0.0, 1.0],
        },
    ];
    for tfs in [&two[..0], &two[..]] {
        let m = TfMessage {
            transforms: tfs.to_vec(),
        };
        cases.push((tf_of(tfs), m.to_cdr().unwrap(), TfMessage::SCHEMA));
    }
    // arrays of class fractions: none, and six (the doubles start 8-aligned after the label)
    for data in [vec![], vec![0.0, 0.25, 0.5, 0.125, 0.125, 1e-300]] {
        for label in ["outside,sky,cloud,obstruction,ground,sun", "x"] {
            let a = Float64MultiArray {
                label: label.into(),
                data: data.clone(),
            };
            cases.push((
                json!({"kind": "float64_array", "value": {"label": label, "data": data}}),
                a.to_cdr().unwrap(),
                Float64MultiArray::SCHEMA,
            ));
        }
    }
    let file = d.path().join("cases.json");
    let values: Vec<_> = cases.iter().map(|c| c.0.clone()).collect();
    std::fs::write(&file, serde_json::to_string(&values).unwrap()).unwrap();
    let out = check(&["cdr", s(&file)]);
    let lines: Vec<serde_json::Value> = out
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), cases.len());
    for ((v, ours, schema), theirs) in cases.iter().zip(&lines) {
        let hex: String = ours.iter().map(|b| format!("{b:02x}")).collect();
        assert_eq!(hex, theirs["cdr"].as_str().unwrap(), "CDR of {v}");
        assert_eq!(
            *schema,
            theirs["msgdef"].as_str().unwrap(),
            "schema of {}",
            theirs["type"]
        );
    }
}

#[test]
fn stream_bag_reads_in_both_readers_and_matches_the_stream() {
    let d = tempfile::tempdir().unwrap();
    let traj = trajectory(d.path());
    let opts = [
        &SMALL[..],
        &[
            "--trajectory",
            s(&traj),
            "--pixel-format",
            "mono12p",
            "--seed",
            "7",
        ],
    ]
    .concat();
    let psns_file = d.path().join("run.psns");
    stream(&[&opts[..], &["--out", s(&psns_file)]].concat());
    let bag = d.path().join("run");
    stream(&[&opts[..], &["--format", "rosbag2", "--out", s(&bag)]].concat());
    let out = check(&["bag", s(&bag), s(&psns_file)]);
    assert!(out.contains("ok: 4 frames, 5 topics"), "{out}");
    // rosbag2's layout: metadata.yaml and <name>_0.mcap, nothing else
    let mut names: Vec<String> = std::fs::read_dir(&bag)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    assert_eq!(names, ["metadata.yaml", "run_0.mcap"]);
    let y = std::fs::read_to_string(bag.join("metadata.yaml")).unwrap();
    assert!(
        y.contains("  version: 8\n  storage_identifier: mcap\n"),
        "{y}"
    );
    // the same with zstd chunks
    let z = d.path().join("z");
    stream(
        &[
            &opts[..],
            &[
                "--format",
                "rosbag2",
                "--compression",
                "zstd",
                "--out",
                s(&z),
            ],
        ]
        .concat(),
    );
    check(&["bag", s(&z), s(&psns_file)]);
}

#[test]
fn bare_mcap_of_a_mono8_fisheye_reads_in_both_readers() {
    let d = tempfile::tempdir().unwrap();
    let opts = [
        &SMALL[..],
        &[
            "--frames",
            "3",
            "--pixel-format",
            "mono8",
            "--projection",
            "equidistant",
            "--focal-length",
            "0.2",
        ],
    ]
    .concat();
    let psns_file = d.path().join("run.psns");
    stream(&[&opts[..], &["--out", s(&psns_file)]].concat());
    let m = d.path().join("run.mcap");
    stream(&[&opts[..], &["--format", "mcap", "--out", s(&m)]].concat());
    let out = check(&["bag", s(&m), s(&psns_file)]);
    assert!(out.contains("ok: 3 frames"), "{out}");
}

/// Every file of a bag (directory or file), by name.
fn bag_bytes(p: &Path) -> Vec<(String, Vec<u8>)> {
    if p.is_file() {
        return vec![("file".into(), std::fs::read(p).unwrap())];
    }
    let mut v: Vec<(String, Vec<u8>)> = std::fs::read_dir(p)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            (
                e.file_name().to_string_lossy().into_owned(),
                std::fs::read(e.path()).unwrap(),
            )
        })
        .collect();
    v.sort();
    v
}

#[test]
fn convert_of_a_stream_equals_the_direct_bag() {
    let d = tempfile::tempdir().unwrap();
    let traj = trajectory(d.path());
    for (fmt, pix, comp) in [
        ("rosbag2", "mono12packed", "none"),
        ("rosbag2", "mono8", "zstd"),
        ("mcap", "mono16", "none"),
    ] {
        let opts = [
            &SMALL[..],
            &["--trajectory", s(&traj), "--pixel-format", pix],
        ]
        .concat();
        let sub = d.path().join(format!("{fmt}-{pix}"));
        for x in ["direct", "file", "stdin"] {
            std::fs::create_dir_all(sub.join(x)).unwrap();
        }
        let name = if fmt == "mcap" { "bag.mcap" } else { "bag" };
        let direct = sub.join("direct").join(name);
        let bag_opts = ["--format", fmt, "--compression", comp];
        stream(&[&opts[..], &bag_opts, &["--out", s(&direct)]].concat());
        let psns_file = sub.join("run.psns");
        stream(&[&opts[..], &["--out", s(&psns_file)]].concat());
        let conv = sub.join("file").join(name);
        let o = psns(
            &[
                &["convert", s(&psns_file)],
                &bag_opts[..],
                &["--out", s(&conv)],
            ]
            .concat(),
        );
        assert!(o.status.success(), "{}", stderr(&o));
        assert!(stderr(&o).contains("converted 4 frames"), "{}", stderr(&o));
        assert_eq!(bag_bytes(&direct), bag_bytes(&conv), "{fmt} {pix} {comp}");
        // from a pipe: the stream on stdin (count 0, LAST on the file trajectory's last frame)
        let piped = psns(&[&["stream"], &opts[..], &["--out", "-"]].concat());
        assert!(piped.status.success());
        let conv2 = sub.join("stdin").join(name);
        let mut c = Command::new(env!("CARGO_BIN_EXE_psns"))
            .args([&["convert", "-"], &bag_opts[..], &["--out", s(&conv2)]].concat())
            .stdin(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        use std::io::Write;
        c.stdin.take().unwrap().write_all(&piped.stdout).unwrap();
        let o = c.wait_with_output().unwrap();
        assert!(o.status.success(), "{}", stderr(&o));
        assert_eq!(bag_bytes(&direct), bag_bytes(&conv2), "stdin {fmt} {pix}");
        check(&["bag", s(&conv), s(&psns_file)]);
    }
}

#[test]
fn a_world_adds_the_class_fractions_topic() {
    let d = tempfile::tempdir().unwrap();
    // a zenith fisheye in a street canyon: every class but cloud and sun in view
    let opts = [
        &SMALL[..],
        &[
            "--frames",
            "3",
            "--projection",
            "equidistant",
            "--focal-length",
            "0.2",
            "--canyon",
            "20,6,30",
        ],
    ]
    .concat();
    let psns_file = d.path().join("run.psns");
    stream(&[&opts[..], &["--out", s(&psns_file)]].concat());
    for x in ["direct", "conv"] {
        std::fs::create_dir_all(d.path().join(x)).unwrap();
    }
    let bag = d.path().join("direct/run");
    stream(&[&opts[..], &["--format", "rosbag2", "--out", s(&bag)]].concat());
    // the checker holds each frame's message to the stream header's fractions
    let out = check(&["bag", s(&bag), s(&psns_file)]);
    assert!(out.contains("ok: 3 frames, 6 topics"), "{out}");
    let y = std::fs::read_to_string(bag.join("metadata.yaml")).unwrap();
    assert!(y.contains("name: \"/psns/truth/classes\""), "{y}");
    // converted from the stream: the same bag
    let conv = d.path().join("conv/run");
    let o = psns(&[
        "convert",
        s(&psns_file),
        "--format",
        "rosbag2",
        "--out",
        s(&conv),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert_eq!(bag_bytes(&bag), bag_bytes(&conv));
}

#[test]
fn truth_images_equal_render_raw_truth() {
    let d = tempfile::tempdir().unwrap();
    let bag = d.path().join("t");
    let psns_file = d.path().join("t.psns");
    // the built-in turning camera: frame 0 looks at the zenith with yaw 0 in ENU
    let opts = [&SMALL[..], &["--frames", "2"]].concat();
    stream(
        &[
            &opts[..],
            &["--format", "rosbag2", "--truth-images", "--out", s(&bag)],
        ]
        .concat(),
    );
    stream(&[&opts[..], &["--out", s(&psns_file)]].concat());
    let out = check(&["bag", s(&bag), s(&psns_file), "--truth"]);
    assert!(out.contains("7 topics"), "{out}");
    let r = d.path().join("render");
    let o = psns(
        &[
            &[
                "render",
                "--raw",
                "--frame",
                "enu",
                "--yaw",
                "0",
                "--out",
                s(&r),
            ],
            &SMALL[..],
        ]
        .concat(),
    );
    assert!(o.status.success(), "{}", stderr(&o));
    check(&["truth", s(&bag), s(&r)]);
}

#[test]
fn bad_input_exits_2_and_writes_nothing() {
    let d = tempfile::tempdir().unwrap();
    let full = d.path().join("full");
    std::fs::create_dir(&full).unwrap();
    std::fs::write(full.join("notes.txt"), "mine").unwrap();
    let fresh = d.path().join("fresh");
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["--format", "rosbag2", "--out", s(&full)], "not empty"),
        (vec!["--format", "ros1", "--out", s(&fresh)], "ros1"),
        (
            vec!["--compression", "zstd", "--out", s(&fresh)],
            "--format rosbag2",
        ),
        (
            vec!["--truth-images", "--out", s(&fresh)],
            "--format rosbag2",
        ),
        (vec!["--format", "rosbag2", "--out", "-"], "stdout"),
        (
            vec!["--format", "mcap", "--out", s(d.path())],
            "is a directory",
        ),
        (
            vec![
                "--format",
                "rosbag2",
                "--start-time",
                "2040-01-01T00:00:00Z",
                "--out",
                s(&fresh),
            ],
            "2038-01-19",
        ),
        (
            vec![
                "--format",
                "rosbag2",
                "--stamp-host-time",
                "--out",
                s(&fresh),
            ],
            "psns format",
        ),
    ];
    for (args, msg) in cases {
        let o = psns(&[&["stream", "--frames", "2"], &SMALL[..], &args[..]].concat());
        assert_eq!(o.status.code(), Some(2), "{args:?}: {}", stderr(&o));
        assert!(stderr(&o).contains(msg), "{args:?}: {}", stderr(&o));
        assert!(!fresh.exists(), "{args:?} wrote {}", fresh.display());
    }
    assert_eq!(
        bag_bytes(&full).len(),
        1,
        "the foreign directory was touched"
    );
    // convert: not a stream; a damaged stream; the psns format
    let png = d.path().join("x.png");
    std::fs::write(&png, b"\x89PNG\r\n\x1a\n not a stream at all").unwrap();
    let o = psns(&[
        "convert",
        s(&png),
        "--format",
        "rosbag2",
        "--out",
        s(&fresh),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("not a psns stream"), "{}", stderr(&o));
    assert!(!fresh.exists());
    let good = d.path().join("good.psns");
    stream(&[&SMALL[..], &["--frames", "3", "--out", s(&good)]].concat());
    let mut b = std::fs::read(&good).unwrap();
    let stride = (b.len() - 4096) / 3;
    b[4096 + stride + 256 + 100] ^= 0x40; // frame 1's payload
    let bad = d.path().join("bad.psns");
    std::fs::write(&bad, &b).unwrap();
    for fmt in ["rosbag2", "mcap"] {
        let o = psns(&["convert", s(&bad), "--format", fmt, "--out", s(&fresh)]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains("frame 1 is damaged"), "{}", stderr(&o));
        assert!(!fresh.exists(), "a damaged stream left {}", fresh.display());
    }
    let o = psns(&["convert", s(&good), "--format", "psns", "--out", s(&fresh)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(!fresh.exists());
    // an empty directory is fine
    let empty = d.path().join("empty");
    std::fs::create_dir(&empty).unwrap();
    let o = psns(&[
        "convert",
        s(&good),
        "--format",
        "rosbag2",
        "--out",
        s(&empty),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(empty.join("metadata.yaml").exists());
}

#[test]
fn a_bad_trajectory_line_leaves_an_unfinished_bag() {
    let d = tempfile::tempdir().unwrap();
    let bag = d.path().join("b");
    let input = "t_s,yaw_deg,pitch_deg,roll_deg\n0,0,0,0\n0.1,10,0,0\n0.05,20,0,0\n";
    let o = psns_stdin(
        &[
            &["stream", "--trajectory", "-", "--format", "rosbag2"],
            &SMALL[..],
            &["--out", s(&bag)],
        ]
        .concat(),
        input,
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains("trajectory line 4"), "{e}");
    assert!(e.contains("left unfinished"), "{e}");
    // the run failed: the bag must not read as whole
    assert!(!bag.join("metadata.yaml").exists());
    let r = check(&["unfinished", s(&bag)]);
    assert!(r.contains("metadata"), "{r}");
    let r = check(&["unfinished", s(&bag.join("b_0.mcap"))]);
    assert!(r.starts_with("refused: "), "{r}");
}

#[test]
fn a_stopped_run_leaves_an_unfinished_bag_and_dies_by_its_signal() {
    use std::os::unix::process::ExitStatusExt;
    let d = tempfile::tempdir().unwrap();
    let bag = d.path().join("t");
    let child = Command::new(env!("CARGO_BIN_EXE_psns"))
        .args(["stream", "--frames", "1000000", "--format", "rosbag2"])
        .args(SMALL)
        .args(["--out", s(&bag)])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mcap = bag.join("t_0.mcap");
    let t = Instant::now();
    while std::fs::metadata(&mcap).map_or(0, |m| m.len()) < 200_000 {
        assert!(t.elapsed() < Duration::from_secs(60), "producer too slow");
        std::thread::sleep(Duration::from_millis(10));
    }
    let st = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(st.success());
    let o = child.wait_with_output().unwrap();
    assert_eq!(o.status.signal(), Some(15), "SIGTERM");
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("left unfinished"), "{e}");
    assert!(!bag.join("metadata.yaml").exists());
    let r = check(&["unfinished", s(&bag)]);
    assert!(r.contains("metadata"), "{r}");
}

#[test]
fn convert_refuses_an_aborted_stream() {
    let d = tempfile::tempdir().unwrap();
    let input = "t_s,yaw_deg,pitch_deg,roll_deg\n0,0,0,0\n0.1,10,0,0\n0.05,20,0,0\n";
    let traj = d.path().join("t.csv");
    std::fs::write(&traj, input).unwrap();
    // into a file: the header carries the aborted mark; through stdout: only the end record
    let marked = d.path().join("a.psns");
    let o = psns(
        &[
            &["stream", "--trajectory", s(&traj)],
            &SMALL[..],
            &["--out", s(&marked)],
        ]
        .concat(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let o = psns(
        &[
            &["stream", "--trajectory", s(&traj)],
            &SMALL[..],
            &["--out", "-"],
        ]
        .concat(),
    );
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let piped = d.path().join("p.psns");
    std::fs::write(&piped, &o.stdout).unwrap();
    for run in [&marked, &piped] {
        let bag = d.path().join("b");
        let o = psns(&["convert", s(run), "--format", "rosbag2", "--out", s(&bag)]);
        assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
        assert!(stderr(&o).contains("aborted"), "{}", stderr(&o));
        assert!(!bag.exists(), "{}", run.display());
    }
}

#[test]
fn a_full_disk_leaves_a_clearly_unfinished_bag_exit_1() {
    let d = tempfile::tempdir().unwrap();
    // the bare MCAP file onto /dev/full: nothing can be written
    let o = psns(
        &[
            &[
                "stream",
                "--frames",
                "3",
                "--format",
                "mcap",
                "--out",
                "/dev/full",
            ],
            &SMALL[..],
        ]
        .concat(),
    );
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    assert!(stderr(&o).contains("unfinished"), "{}", stderr(&o));
    // a bag directory on a 1 MiB tmpfs (needs root, as CI and these machines run): 30 frames of
    // 256 x 256 Mono16 are 3.9 MB
    let mnt = d.path().join("mnt");
    std::fs::create_dir(&mnt).unwrap();
    let st = Command::new("mount")
        .args(["-t", "tmpfs", "-o", "size=1m", "tmpfs", s(&mnt)])
        .status()
        .expect("mount(8)");
    assert!(
        st.success(),
        "mounting a small tmpfs needs root (CI runs as root)"
    );
    struct Umount<'a>(&'a Path);
    impl Drop for Umount<'_> {
        fn drop(&mut self) {
            let _ = Command::new("umount").arg(self.0).status();
        }
    }
    let _u = Umount(&mnt);
    for fmt in ["rosbag2", "mcap"] {
        let out = mnt.join(if fmt == "mcap" { "b.mcap" } else { "b" });
        let o = psns(&[
            "stream",
            "--frames",
            "30",
            "--width",
            "256",
            "--height",
            "256",
            "--format",
            fmt,
            "--out",
            s(&out),
        ]);
        assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
        let e = stderr(&o);
        assert!(
            e.contains("unfinished") && e.contains("No space left"),
            "{e}"
        );
        // said once, in the error
        assert_eq!(e.matches("left unfinished").count(), 1, "{e}");
        if fmt == "rosbag2" {
            assert!(!out.join("metadata.yaml").exists());
        }
        let r = check(&["unfinished", s(&out)]);
        assert!(r.starts_with("refused: "), "{r}");
        if fmt == "rosbag2" {
            std::fs::remove_dir_all(&out).unwrap();
        } else {
            std::fs::remove_file(&out).unwrap();
        }
    }
}

#[test]
fn a_killed_run_leaves_an_unfinished_bag() {
    let d = tempfile::tempdir().unwrap();
    let bag = d.path().join("k");
    let mut child = Command::new(env!("CARGO_BIN_EXE_psns"))
        .args(["stream", "--frames", "1000000", "--format", "rosbag2"])
        .args(SMALL)
        .args(["--out", s(&bag)])
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mcap = bag.join("k_0.mcap");
    let t = Instant::now();
    while std::fs::metadata(&mcap).map_or(0, |m| m.len()) < 200_000 {
        assert!(t.elapsed() < Duration::from_secs(60), "producer too slow");
        std::thread::sleep(Duration::from_millis(10));
    }
    child.kill().unwrap(); // SIGKILL: no summary, no footer, no metadata.yaml
    child.wait().unwrap();
    assert!(!bag.join("metadata.yaml").exists());
    let r = check(&["unfinished", s(&bag)]);
    assert!(r.contains("metadata"), "{r}");
    let r = check(&["unfinished", s(&mcap)]);
    assert!(r.starts_with("refused: "), "{r}");
}

/// The chunks are what docs/ros2.md says: a chunk is closed before the message that finds it
/// over 4 MiB, so a full-size image ends its chunk (the next one opens with that frame's small
/// messages), and small frames share one.
#[test]
fn chunks_hold_an_image_after_the_frame_before_s_small_messages() {
    let d = tempfile::tempdir().unwrap();
    let full = d.path().join("full.mcap");
    stream(&["--frames", "3", "--format", "mcap", "--out", s(&full)]);
    let out = check(&["chunks", s(&full)]);
    let small = "/psns/camera_info /psns/pose /psns/sun /tf";
    assert_eq!(
        out,
        format!("/psns/image_raw\n{small} /psns/image_raw\n{small} /psns/image_raw\n{small}\n")
    );
    let m = d.path().join("small.mcap");
    stream(
        &[
            &SMALL[..],
            &["--frames", "5", "--format", "mcap", "--out", s(&m)],
        ]
        .concat(),
    );
    assert_eq!(check(&["chunks", s(&m)]).lines().count(), 1);
}

/// SIGINT ends a bag run without --frames as `ros2 bag record` does: a finished bag (footer,
/// metadata.yaml) of the frames written, exit 0, that both readers open.
#[test]
fn ctrl_c_finishes_a_bag_both_readers_open() {
    let d = tempfile::tempdir().unwrap();
    for (fmt, name) in [("rosbag2", "c"), ("mcap", "c.mcap")] {
        let bag = d.path().join(name);
        let child = Command::new(env!("CARGO_BIN_EXE_psns"))
            .args([
                "stream",
                "--rate",
                "40",
                "--format",
                fmt,
                "--compression",
                "zstd",
            ])
            .args(SMALL)
            .args(["--out", s(&bag)])
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        std::thread::sleep(Duration::from_millis(700));
        let st = Command::new("kill")
            .args(["-INT", &child.id().to_string()])
            .status()
            .unwrap();
        assert!(st.success());
        let o = common::wait_deadline(child, 30);
        assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
        let e = stderr(&o);
        let n: u64 = e
            .split("streamed ")
            .nth(1)
            .and_then(|r| r.split(' ').next())
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("{e}"));
        assert!(n >= 2, "{e}");
        if fmt == "rosbag2" {
            assert!(bag.join("metadata.yaml").exists());
        }
        // the frames of the same options, as a stream
        let psns_file = d.path().join(format!("{fmt}.psns"));
        let nf = n.to_string();
        stream(&[&SMALL[..], &["--frames", &nf, "--out", s(&psns_file)]].concat());
        let r = check(&["bag", s(&bag), s(&psns_file)]);
        assert!(r.contains(&format!("ok: {n} frames")), "{r}");
    }
}

/// A run of N frames stopped early is aborted, and `psns convert` refuses it; with `--partial`
/// it makes a bag of the intact frames.
#[test]
fn convert_partial_makes_a_bag_of_an_aborted_stream() {
    let d = tempfile::tempdir().unwrap();
    let run = d.path().join("a.psns");
    let child = Command::new(env!("CARGO_BIN_EXE_psns"))
        .args(["stream", "--frames", "1000000", "--rate", "40"])
        .args(SMALL)
        .args(["--out", s(&run)])
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(500));
    let st = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(st.success());
    common::wait_deadline(child, 30);
    let v = psns(&["verify", s(&run)]);
    assert_eq!(v.status.code(), Some(3), "aborted");
    let bag = d.path().join("p");
    let o = psns(&["convert", s(&run), "--format", "rosbag2", "--out", s(&bag)]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--partial"), "{}", stderr(&o));
    assert!(!bag.exists());
    let o = psns(&[
        "convert",
        s(&run),
        "--partial",
        "--format",
        "rosbag2",
        "--out",
        s(&bag),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    assert!(
        stderr(&o).contains("aborted it: stopped by SIGINT"),
        "{}",
        stderr(&o)
    );
    let r = check(&["bag", s(&bag), s(&run)]);
    assert!(r.starts_with("ok: "), "{r}");
}

/// `kill -9` leaves a bag without footer and metadata.yaml; `psns recover` makes a finished bag
/// of every complete message, which both readers open and which holds the stream's frames.
#[test]
fn recover_finishes_a_killed_bag_with_every_complete_message() {
    let d = tempfile::tempdir().unwrap();
    // killed after its first whole chunks (4 MiB each), and inside its first chunk
    for (fmt, name, comp, at) in [
        ("rosbag2", "k", "none", 9 << 20),
        ("mcap", "k.mcap", "zstd", 1 << 20),
    ] {
        let bag = d.path().join(name);
        let mut child = Command::new(env!("CARGO_BIN_EXE_psns"))
            .args([
                "stream",
                "--format",
                fmt,
                "--compression",
                comp,
                "--seed",
                "5",
            ])
            .args(SMALL)
            .args(["--out", s(&bag)])
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let file = if fmt == "mcap" {
            bag.clone()
        } else {
            bag.join("k_0.mcap")
        };
        let t = Instant::now();
        while std::fs::metadata(&file).map_or(0, |m| m.len()) < at {
            assert!(t.elapsed() < Duration::from_secs(60), "producer too slow");
            std::thread::sleep(Duration::from_millis(5));
        }
        child.kill().unwrap();
        child.wait().unwrap();
        let r = check(&["unfinished", s(&bag)]);
        assert!(r.starts_with("refused: "), "{r}");
        let rec = d.path().join(format!("rec-{name}"));
        let o = psns(&["recover", s(&bag), "--out", s(&rec)]);
        assert!(o.status.success(), "{}", stderr(&o));
        let e = stderr(&o);
        let images: u64 = e
            .split("/psns/image_raw ")
            .nth(1)
            .and_then(|r| r.split([',', ')']).next())
            .and_then(|n| n.parse().ok())
            .unwrap_or_else(|| panic!("{e}"));
        assert!(images > 10, "{e}");
        if fmt == "rosbag2" {
            assert!(rec.join("metadata.yaml").exists());
        }
        let psns_file = d.path().join(format!("{fmt}.psns"));
        let nf = images.to_string();
        stream(
            &[
                &SMALL[..],
                &["--seed", "5", "--frames", &nf, "--out", s(&psns_file)],
            ]
            .concat(),
        );
        let r = check(&["recovered", s(&rec), s(&psns_file)]);
        assert!(r.starts_with("ok: "), "{r}");
    }
}
