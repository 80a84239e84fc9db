//! `psns bench gige`: the frames per second an Aravis receiver gets from `psns gige` on this
//! machine, with Aravis's own fake camera measured the same way in the same run.
//!
//! The receiver is `arv-camera-test-0.8 -n ADDR -f 200 -i 8192 --duration D` (a 200 Hz frame
//! rate asked for, packet size 8192), on the same cores as the device. Its per-second lines give
//! the rate (median of the seconds after the first two); its closing statistics give the failed
//! buffers. The CPU time of the device and of the receiver over the run (from /proc and wait4)
//! say where the time goes.

use psns::error::{Error, Result};
use psns::gige::gvsp::{self, BlockLayout};
use psns::io::create_dir;
use std::io::{BufRead, BufReader, Read, Write};
use std::net::Ipv4Addr;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// Options of `psns bench gige`.
pub struct GigeBenchOptions {
    /// Output directory (gige.csv, gige.md).
    pub out: PathBuf,
    /// Seconds of each receiver run.
    pub duration_s: u32,
    /// Runs per case (median reported, with the slowest and fastest).
    pub runs: usize,
}

/// Which device a case runs.
#[derive(Clone, Copy, PartialEq)]
enum Dev {
    Psns,
    Fake,
}

struct Case {
    name: &'static str,
    dev: Dev,
    /// Features set through arv-camera-test's --features.
    features: &'static str,
    /// Bytes of one frame's payload (for the throughput limit's rate).
    payload: usize,
    /// DeviceLinkThroughputLimit, bytes/s.
    limit: Option<u64>,
}

/// One run of one case.
#[derive(Clone, Debug, Default)]
struct Sample {
    fps: f64,
    completed: u64,
    failures: u64,
    device_cpu_s: f64,
    receiver_cpu_s: f64,
}

const PACKET_SIZE: u32 = 8192;

/// The frame rate a link of `rate` bytes/s gives `payload`-byte blocks at `PACKET_SIZE`: every
/// packet (leader, data, trailer) with its IP, UDP and Ethernet framing, as `psns gige` paces.
pub fn link_rate_fps(payload: usize, rate: u64) -> f64 {
    let l = BlockLayout::new(payload, PACKET_SIZE);
    let per = 28 + 38;
    let mut wire =
        (gvsp::HEADER_LEN + gvsp::LEADER_LEN + per) + (gvsp::HEADER_LEN + gvsp::TRAILER_LEN + per);
    wire += payload + l.data_packets() as usize * (gvsp::HEADER_LEN + per);
    rate as f64 / wire as f64
}

fn cases() -> Vec<Case> {
    let full = 2448 * 2048;
    vec![
        Case {
            name: "psns gige, Mono8 2448 x 2048",
            dev: Dev::Psns,
            features: "",
            payload: full,
            limit: None,
        },
        Case {
            name: "psns gige, Mono16 2448 x 2048",
            dev: Dev::Psns,
            features: "PixelFormat=Mono16",
            payload: 2 * full,
            limit: None,
        },
        Case {
            name: "psns gige, Mono8, DeviceLinkThroughputLimit 125 MB/s",
            dev: Dev::Psns,
            features: "DeviceLinkThroughputLimitMode=On DeviceLinkThroughputLimit=125000000",
            payload: full,
            limit: Some(125_000_000),
        },
        Case {
            name: "Aravis fake camera, defaults (Mono8 512 x 512, 10 ms exposure)",
            dev: Dev::Fake,
            features: "",
            payload: 512 * 512,
            limit: None,
        },
        Case {
            name: "Aravis fake camera, Mono8 2048 x 2048",
            dev: Dev::Fake,
            features: "Width=2048 Height=2048",
            payload: 2048 * 2048,
            limit: None,
        },
    ]
}

/// CPU seconds (user + system) of a running process, from /proc.
fn cpu_seconds(pid: u32) -> f64 {
    let Ok(s) = std::fs::read_to_string(format!("/proc/{pid}/stat")) else {
        return f64::NAN;
    };
    // fields after the command name (which may hold spaces) in parentheses
    let rest = s.rsplit_once(')').map(|(_, r)| r).unwrap_or("");
    let f: Vec<&str> = rest.split_whitespace().collect();
    // SAFETY: sysconf has no preconditions
    let tck = unsafe { libc::sysconf(libc::_SC_CLK_TCK) } as f64;
    let ticks = |i: usize| {
        f.get(i)
            .and_then(|v| v.parse::<f64>().ok())
            .unwrap_or(f64::NAN)
    };
    // utime and stime are fields 14 and 15 of the line, 12 and 13 after the state
    (ticks(11) + ticks(12)) / tck
}

struct Device {
    child: Child,
    addr: Ipv4Addr,
}

impl Drop for Device {
    fn drop(&mut self) {
        // SAFETY: kill(2) on the pid of a child this process spawned and has not reaped
        unsafe {
            libc::kill(self.child.id() as i32, libc::SIGTERM);
        }
        let t0 = Instant::now();
        while t0.elapsed() < Duration::from_secs(10) {
            if let Ok(Some(_)) = self.child.try_wait() {
                return;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

fn start_device(dev: Dev, exe: &str) -> Result<Device> {
    match dev {
        Dev::Psns => {
            for last in 2..20u8 {
                let addr = Ipv4Addr::new(127, 0, 0, last);
                let mut child = Command::new(exe)
                    .args(["gige", "--address", &addr.to_string()])
                    .env("PSNS_PROGRESS", "off")
                    .stdin(Stdio::null())
                    .stdout(Stdio::null())
                    .stderr(Stdio::piped())
                    .spawn()
                    .map_err(|e| Error::io("starting psns gige", e))?;
                let mut err = BufReader::new(child.stderr.take().expect("piped"));
                let mut line = String::new();
                let _ = err.read_line(&mut line);
                if line.contains("listening on") {
                    // keep reading its stderr so it never blocks on a full pipe
                    std::thread::spawn(move || {
                        let _ = std::io::copy(&mut err, &mut std::io::sink());
                    });
                    return Ok(Device { child, addr });
                }
                let _ = err.read_to_string(&mut line);
                let _ = child.wait();
                if !line.contains("in use") {
                    return Err(Error::Invalid(format!("psns gige did not start: {line}")));
                }
            }
            Err(Error::Invalid(
                "no free loopback address for psns gige".into(),
            ))
        }
        Dev::Fake => {
            let child = Command::new("arv-fake-gv-camera-0.8")
                .args(["-i", "127.0.0.1"])
                .stdin(Stdio::null())
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .map_err(|e| {
                    Error::io(
                        "starting arv-fake-gv-camera-0.8 (apt-get install aravis-tools)",
                        e,
                    )
                })?;
            let d = Device {
                child,
                addr: Ipv4Addr::LOCALHOST,
            };
            // ready when it answers by address
            let t0 = Instant::now();
            while t0.elapsed() < Duration::from_secs(20) {
                let o = Command::new("arv-tool-0.8")
                    .args(["-a", "127.0.0.1", "control", "DeviceVendorName"])
                    .output();
                if o.is_ok_and(|o| String::from_utf8_lossy(&o.stdout).contains("Aravis")) {
                    return Ok(d);
                }
                std::thread::sleep(Duration::from_millis(200));
            }
            Err(Error::Invalid(
                "the Aravis fake camera did not answer on 127.0.0.1 (is 127.0.0.1:3956 taken?)"
                    .into(),
            ))
        }
    }
}

/// Runs the receiver against a fresh device for `duration_s`.
fn run_once(case: &Case, exe: &str, duration_s: u32) -> Result<Sample> {
    let dev = start_device(case.dev, exe)?;
    let mut args = vec![
        "-n".to_string(),
        dev.addr.to_string(),
        "-f".into(),
        "200".into(),
        "-i".into(),
        PACKET_SIZE.to_string(),
        "--duration".into(),
        duration_s.to_string(),
    ];
    if !case.features.is_empty() {
        args.push("--features".into());
        args.push(case.features.into());
    }
    let dev_cpu0 = cpu_seconds(dev.child.id());
    let mut rx = Command::new("arv-camera-test-0.8")
        .args(&args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .map_err(|e| {
            Error::io(
                "starting arv-camera-test-0.8 (apt-get install aravis-tools)",
                e,
            )
        })?;
    let mut out = String::new();
    rx.stdout
        .take()
        .expect("piped")
        .read_to_string(&mut out)
        .map_err(|e| Error::io("reading arv-camera-test-0.8", e))?;
    let mut status = 0;
    // SAFETY: rusage is plain C data; all zeroes is a valid value
    let mut ru: libc::rusage = unsafe { std::mem::zeroed() };
    // SAFETY: wait4 reaps this child (spawned above, not waited for) and writes status and ru,
    // both live locals
    let r = unsafe { libc::wait4(rx.id() as i32, &mut status, 0, &mut ru) };
    let dev_cpu = cpu_seconds(dev.child.id()) - dev_cpu0;
    drop(dev);
    let tv = |t: libc::timeval| t.tv_sec as f64 + t.tv_usec as f64 * 1e-6;
    let rx_cpu = if r > 0 {
        tv(ru.ru_utime) + tv(ru.ru_stime)
    } else {
        f64::NAN
    };
    let per_second: Vec<f64> = out
        .lines()
        .filter_map(|l| l.trim().split_once(" frame"))
        .filter_map(|(n, _)| n.trim().parse::<f64>().ok())
        .collect();
    let stat = |k: &str| -> u64 {
        out.lines()
            .find_map(|l| l.strip_prefix(k).and_then(|r| r.trim().strip_prefix('=')))
            .and_then(|v| v.trim().parse().ok())
            .unwrap_or(u64::MAX)
    };
    if per_second.len() < 3 {
        return Err(Error::Invalid(format!(
            "arv-camera-test-0.8 gave no rate for {}:\n{out}",
            case.name
        )));
    }
    Ok(Sample {
        fps: median(per_second[2..].to_vec()),
        completed: stat("n_completed_buffers"),
        failures: stat("n_failures"),
        device_cpu_s: dev_cpu,
        receiver_cpu_s: rx_cpu,
    })
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(|a, b| a.total_cmp(b));
    v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
}

fn machine() -> String {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|c| {
            c.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, m)| m.trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    format!("{cpu}, {cores} cores")
}

fn load() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .map(|l| l.split_whitespace().take(3).collect::<Vec<_>>().join(" "))
        .unwrap_or_default()
}

/// Runs the benchmark; returns the files written.
pub fn bench_gige(o: &GigeBenchOptions) -> Result<Vec<String>> {
    create_dir(&o.out)?;
    let exe = std::env::current_exe().map_err(|e| Error::io("finding the psns binary", e))?;
    let exe = exe.display().to_string();
    let cases = cases();
    let load_before = load();
    // runs interleaved, so that a slow minute of the shared machine hits every case alike
    let mut samples: Vec<Vec<Sample>> = vec![Vec::new(); cases.len()];
    for run in 0..o.runs {
        for (i, c) in cases.iter().enumerate() {
            let s = run_once(c, &exe, o.duration_s)?;
            eprintln!(
                "run {}: {:.1} frames/s, {} failed, CPU device {:.1} s, receiver {:.1} s  {}",
                run + 1,
                s.fps,
                s.failures,
                s.device_cpu_s,
                s.receiver_cpu_s,
                c.name
            );
            samples[i].push(s);
        }
    }
    let mut csv = String::from(
        "case,runs,fps_median,fps_min,fps_max,failed_buffers,completed_buffers,device_cpu_ms_per_frame,receiver_cpu_ms_per_frame,link_fps\n",
    );
    let mut md = format!(
        "Machine: {}; load average before the runs {load_before}, after {}; {} runs of {} s per case, interleaved; receiver `arv-camera-test-0.8 -n ADDR -f 200 -i 8192 --duration {}`.\n\n\
         | case | frames/s (median, min–max) | failed buffers | device CPU ms/frame | receiver CPU ms/frame |\n|---|---|---|---|---|\n",
        machine(),
        load(),
        o.runs,
        o.duration_s,
        o.duration_s
    );
    for (c, s) in cases.iter().zip(&samples) {
        let fps: Vec<f64> = s.iter().map(|x| x.fps).collect();
        let (lo, hi) = (
            fps.iter().copied().fold(f64::INFINITY, f64::min),
            fps.iter().copied().fold(0.0, f64::max),
        );
        let med = median(fps.clone());
        let failed: u64 = s.iter().map(|x| x.failures).sum();
        let done: u64 = s.iter().map(|x| x.completed).sum();
        let per = |f: fn(&Sample) -> f64| {
            median(
                s.iter()
                    .map(|x| 1e3 * f(x) / (x.completed.max(1) as f64))
                    .collect(),
            )
        };
        let (dcpu, rcpu) = (per(|x| x.device_cpu_s), per(|x| x.receiver_cpu_s));
        let link = c.limit.map(|r| link_rate_fps(c.payload, r));
        csv.push_str(&format!(
            "\"{}\",{},{med:.2},{lo:.2},{hi:.2},{failed},{done},{dcpu:.2},{rcpu:.2},{}\n",
            c.name,
            s.len(),
            link.map_or(String::new(), |l| format!("{l:.2}"))
        ));
        let name = match link {
            Some(l) => format!("{} (a 125 MB/s link carries {l:.2} frames/s)", c.name),
            None => c.name.to_string(),
        };
        md.push_str(&format!(
            "| {name} | {med:.1} ({lo:.1}–{hi:.1}) | {failed} of {done} | {dcpu:.1} | {rcpu:.1} |\n"
        ));
    }
    let mut files = Vec::new();
    for (name, body) in [("gige.csv", &csv), ("gige.md", &md)] {
        let p = o.out.join(name);
        let mut f = std::fs::File::create(&p)
            .map_err(|e| Error::io(format!("creating {}", p.display()), e))?;
        f.write_all(body.as_bytes())
            .map_err(|e| Error::io(format!("writing {}", p.display()), e))?;
        files.push(p.display().to_string());
    }
    print!("{md}");
    Ok(files)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn link_rate_counts_every_packet_with_its_framing() {
        // Mono8 2448 x 2048 at packet size 8192: 615 data packets of 8164 bytes (the last
        // shorter), a leader and a trailer, each with 66 bytes of IP, UDP and Ethernet
        let fps = link_rate_fps(2448 * 2048, 125_000_000);
        let wire = 2448.0 * 2048.0 + 615.0 * (8.0 + 66.0) + (44.0 + 66.0) + (16.0 + 66.0);
        assert!((fps - 125e6 / wire).abs() < 1e-9, "{fps}");
        assert!((24.0..25.0).contains(&fps));
    }

    #[test]
    fn cpu_of_this_process_is_read() {
        let c = cpu_seconds(std::process::id());
        assert!(c.is_finite() && c >= 0.0, "{c}");
    }
}
