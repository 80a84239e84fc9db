#!/usr/bin/env python3
"""Example navigation program: follows a live `psns stream` (FIFO, growing file or stdin) and
estimates the sun's direction from the polarization at the image centre. Needs numpy only (and the
stream reader psns_stream.py next to this file).

    mkfifo /tmp/cam.fifo
    psns stream --out /tmp/cam.fifo --frames 100 --rate 20 &
    tools/nav_reader.py /tmp/cam.fifo

One line per frame, as it arrives:

    frame 3 t=2025-06-21T10:00:00.150Z flags=0x0002 mean=516.9 sun_az=200.00 sun_el=40.00 aolp=72.3 expected=73.1 err=-0.8

- mean: mean raw code (payload DN);
- aolp: angle of linear polarization measured at the image centre from the 2 x 2 superpixels
  (degrees in the sensor frame, from +x (columns) toward +y (rows)), black level removed;
- expected: single-scattering prediction, perpendicular to the plane through the optical axis
  and the sun: the angle of z x s = (-s_y, s_x) with s the sun unit vector in the camera frame from
  the frame header; err = aolp - expected wrapped to [-90, 90). A heading filter would fuse this
  with the ephemeris sun azimuth to get yaw modulo 180 degrees.
- dolp: degree of linear polarization of the same superpixel sums, black level removed;
- latency_ms (only if the producer ran with --stamp-host-time): host CLOCK_MONOTONIC now minus
  the frame's write stamp.

Options: --max N stops after N frames (closing the stream early); --delay S sleeps S seconds per
frame (a slow consumer); --centre F uses the central fraction F of each axis (default 0.25).
Dropped frames (index gaps), damaged or truncated records and producer restarts are reported as
the stream is read (a restart may change the layout: the new header is used). Exit status 0 after
the stream ends cleanly, 1 if a frame was dropped, damaged or truncated.
"""
import datetime
import os
import sys
import time

try:
    import numpy as np
except ImportError:  # a message, not a traceback
    sys.exit("nav_reader.py needs numpy: python3 -m pip install numpy "
             "(or use the project's .venv made by tools/test)")

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import psns_stream as ps  # noqa: E402


def centre_aolp(values, hdr, black, frac):
    """(AoLP deg in the sensor frame, DoLP) of the summed superpixels in the central fraction of
    the image; `black` is in the units of `values` (see psns_stream.black_level_values)."""
    h, w = values.shape
    v = values.astype(np.float64) - black
    r0 = int(h * (1 - frac) / 2) & ~1
    c0 = int(w * (1 - frac) / 2) & ~1
    r1 = max(r0 + 2, (h - r0) & ~1)
    c1 = max(c0 + 2, (w - c0) & ~1)
    v = v[r0:r1, c0:c1]
    inten = {}
    for k, ang in enumerate(hdr["angles_deg"]):
        dr, dc = divmod(k, 2)
        inten[ang % 180] = v[dr::2, dc::2].sum()
    s0 = 0.5 * sum(inten.values())
    s1 = inten[0] - inten[90]
    s2 = inten[45] - inten[135]
    dolp = np.hypot(s1, s2) / s0 if s0 > 0 else float("nan")
    return 0.5 * np.degrees(np.arctan2(s2, s1)) * hdr["angle_sense"] % 180.0, dolp


def wrap90(a):
    return (a + 90.0) % 180.0 - 90.0


def iso(ns):
    t = datetime.datetime.fromtimestamp(ns // 10**9, datetime.timezone.utc)
    return t.strftime("%Y-%m-%dT%H:%M:%S") + ".%03dZ" % (ns % 10**9 // 10**6)


def main(argv):
    args = argv[1:]
    opts = {"--max": None, "--delay": 0.0, "--centre": 0.25}
    path = None
    while args:
        a = args.pop(0)
        if a in opts:
            opts[a] = float(args.pop(0))
        elif path is None:
            path = a
        else:
            print(__doc__, file=sys.stderr)
            return 2
    if path is None:
        print(__doc__, file=sys.stderr)
        return 2
    f = sys.stdin.buffer if path == "-" else open(path, "rb", buffering=0)
    head = f.read(4096)
    while len(head) < 4096:  # an unbuffered FIFO read may return less
        more = f.read(4096 - len(head))
        if not more:
            break
        head += more
    hdr = ps.parse_header(head)
    print("stream %d x %d %s %d bits, preset %s, producer %s" % (
        hdr["width"], hdr["height"], hdr["pixel_format"], hdr["bits_valid"], hdr["preset"],
        hdr["producer"]), flush=True)
    damaged = []
    aborted = None
    dropped = 0
    n = 0
    for ev in ps.iter_events(ps._Prefixed(head, f)):
        kind = ev[0]
        if kind == "restart":
            hdr = ev[1]
            print("producer restart: %d x %d %s %d bits" % (
                hdr["width"], hdr["height"], hdr["pixel_format"], hdr["bits_valid"]), flush=True)
            continue
        if kind == "gap":
            dropped += ev[2] - ev[1]
            print("dropped: frames %d..%d missing" % (ev[1], ev[2] - 1), flush=True)
            continue
        if kind == "aborted":
            aborted = ev[3]
            print(ps.describe(ev), file=sys.stderr, flush=True)
            continue
        if kind != "frame":
            damaged.append(ps.describe(ev))
            continue
        _, meta, values, ok, _ = ev
        if not ok:
            damaged.append("frame %d payload CRC" % meta["index"])
            continue
        sx, sy, _ = meta["sun_camera"]
        expected = np.degrees(np.arctan2(sx, -sy)) % 180.0
        # the header's black level is in payload DN; unpack() shifted MSB-aligned Mono16 down
        black = ps.black_level_values(hdr, meta["black_level"])
        aolp, dolp = centre_aolp(values, hdr, black, opts["--centre"])
        line = ("frame %d t=%s flags=0x%04x mean=%.1f sun_az=%.2f sun_el=%.2f aolp=%.1f "
                "expected=%.1f err=%.1f dolp=%.4f") % (
            meta["index"], iso(meta["exposure_start_ns"]), meta["flags"], values.mean(),
            meta["sun_azimuth_deg"], meta["sun_elevation_deg"], aolp, expected,
            wrap90(aolp - expected), dolp)
        if meta["host_time_ns"]:
            line += " latency_ms=%.2f" % ((time.clock_gettime_ns(time.CLOCK_MONOTONIC) - meta["host_time_ns"]) / 1e6)
        print(line, flush=True)
        n += 1
        if opts["--max"] is not None and n >= opts["--max"]:
            break
        if opts["--delay"]:
            time.sleep(opts["--delay"])
    for d in damaged:
        print("damage: %s" % d, file=sys.stderr)
    if dropped:
        print("dropped: %d frames (index gaps)" % dropped, file=sys.stderr)
    f.close()
    print("read %d frames, %d dropped, %d damaged" % (n, dropped, len(damaged)), flush=True)
    return 1 if damaged or dropped or aborted is not None else 0


if __name__ == "__main__":
    try:
        sys.exit(main(sys.argv))
    except ps.StreamError as e:
        sys.exit("nav_reader.py: not a valid psns stream: %s" % e)
    except KeyboardInterrupt:  # Ctrl-C: end quietly with the shell's status for SIGINT
        sys.exit(130)
