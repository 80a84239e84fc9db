"""Frames per second of psns from Python against the CLI's stream, on the same machine, in one run
(docs/python.md). Full-size camera preset, 12 bit, a new attitude every frame.

    python python/examples/bench_camera.py [--frames 300] [--psns target/release/psns]
"""

import argparse
import statistics
import subprocess
import time

import psns
import psns.loader


def camera_fps(frames):
    t0 = time.perf_counter()
    cam = psns.Camera(frame="enu")
    t1 = time.perf_counter()
    for i in range(frames):
        cam.frame(yaw=1.2 * i, pitch=2.0, roll=-1.0, frame_index=i)
    t2 = time.perf_counter()
    return frames / (t2 - t1), t1 - t0


def loader_fps(frames, **camera):
    ds = psns.loader.FrameDataset(samples=frames, seed=1, **camera)
    t0 = time.perf_counter()
    n = sum(1 for _ in ds)
    return n / (time.perf_counter() - t0)


def cli_fps(bin_, frames):
    t0 = time.perf_counter()
    subprocess.run([bin_, "stream", "--frames", str(frames), "--out", "/dev/null"], check=True,
                   capture_output=True)
    return frames / (time.perf_counter() - t0)


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--psns", default="target/release/psns")
    a = ap.parse_args()
    rows = {"cli stream (process start included)": [], "Camera.frame": [], "Camera() setup s": [],
            "FrameDataset float32 (full size)": [], "FrameDataset float32 (612x512)": []}
    for _ in range(a.repeat):
        rows["cli stream (process start included)"].append(cli_fps(a.psns, a.frames))
        fps, setup = camera_fps(a.frames)
        rows["Camera.frame"].append(fps)
        rows["Camera() setup s"].append(setup)
        rows["FrameDataset float32 (full size)"].append(loader_fps(a.frames // 3))
        rows["FrameDataset float32 (612x512)"].append(loader_fps(a.frames, width=612, height=512))
    print("what,median,all")
    for k, v in rows.items():
        print(f"{k},{statistics.median(v):.2f},{' '.join(f'{x:.2f}' for x in v)}")
