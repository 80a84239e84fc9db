#!/usr/bin/env python3
"""What a ROS 2 bag costs psns stream: frames/s into /dev/null (psns format) against a rosbag2
bag with plain and with zstd chunks, same pixel format, full size, runs alternated; a psns
stream into a file beside the bags shows what writing the frames to a file costs by itself.

    python3 tools/bench_ros2.py [--psns target/release/psns] [--frames 60] [--runs 5]
                                [--pixel-format mono16] [--dir /dev/shm]

Prints one line per run and a table of medians with each bag's ratio to /dev/null (the stream's
own "streamed N frames in S s (F fps)" line: file header to close, so a bag's summary, sync and
metadata.yaml are inside), and the CPU time (user + system, all threads, the whole process) per
frame, which other jobs on a shared machine disturb less than the rate. The bags go to --dir (a tmpfs by default, so the disk's speed is not
measured) and are removed after each run. Standard library only.
"""

import argparse
import os
import re
import resource
import shutil
import statistics
import subprocess
import sys
import tempfile

RATE = re.compile(r"streamed (\d+) frames in ([0-9.]+) s \(([0-9.]+) fps\)")


def run(psns, args):
    env = dict(os.environ, PSNS_PROGRESS="off")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    p = subprocess.run([psns, "stream", *args], capture_output=True, text=True, env=env)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if p.returncode != 0:
        sys.exit(f"psns stream {' '.join(args)} failed: {p.stderr}")
    m = RATE.search(p.stderr)
    if not m:
        sys.exit(f"no rate in: {p.stderr}")
    return float(m.group(3)), 1e3 * cpu / int(m.group(1))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--psns", default="target/release/psns")
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--pixel-format", default="mono16")
    ap.add_argument("--dir", default="/dev/shm")
    a = ap.parse_args()
    common = ["--frames", str(a.frames), "--pixel-format", a.pixel_format]
    variants = {
        "psns /dev/null": lambda d: common + ["--out", "/dev/null"],
        "psns file": lambda d: common + ["--out", os.path.join(d, "run.psns")],
        "rosbag2, plain chunks": lambda d: common
        + ["--format", "rosbag2", "--out", os.path.join(d, "bag")],
        "rosbag2, zstd chunks": lambda d: common
        + ["--format", "rosbag2", "--compression", "zstd", "--out", os.path.join(d, "bag")],
    }
    fps = {k: [] for k in variants}
    cpu = {k: [] for k in variants}
    for r in range(a.runs):
        for name, args in variants.items():
            d = tempfile.mkdtemp(prefix="psns-bench-ros2-", dir=a.dir)
            try:
                v, c = run(a.psns, args(d))
            finally:
                shutil.rmtree(d)
            fps[name].append(v)
            cpu[name].append(c)
            print(f"run {r + 1}/{a.runs} {name}: {v:.2f} fps, {c:.1f} CPU ms/frame", flush=True)
    base = statistics.median(fps["psns /dev/null"])
    cpu_base = statistics.median(cpu["psns /dev/null"])
    print(f"\n{a.frames} frames, {a.pixel_format}, {a.runs} alternated runs, bags in {a.dir}")
    print(
        "| output | median frames/s | min | max | median / /dev/null "
        "| median CPU ms/frame | /dev/null's / this |"
    )
    print("|---|---|---|---|---|---|---|")
    for name, v in fps.items():
        m = statistics.median(v)
        c = statistics.median(cpu[name])
        print(
            f"| {name} | {m:.1f} | {min(v):.1f} | {max(v):.1f} | {m / base:.3f} "
            f"| {c:.1f} | {cpu_base / c:.3f} |"
        )


if __name__ == "__main__":
    main()
