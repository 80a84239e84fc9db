"""Demosaic an emulated IMX250MZR frame with psns and with polanalyser, and score both against
the emulator's ground truth (docs/python.md).

    python python/examples/compare_polanalyser.py [--width 612 --height 512]
"""

import argparse

import numpy as np
import polanalyser as pa

import psns


def angle_error(a_deg, b_deg):
    """Absolute AoLP difference on the 180-degree circle."""
    d = (a_deg - b_deg + 90.0) % 180.0 - 90.0
    return np.abs(d)


def compare(width=612, height=512, seed=1):
    f = psns.render_raw(width=width, height=height, seed=seed, auto_exposure=True)
    raw, truth = f["raw"], f["truth_aolp"]
    ours = psns.demosaic(raw, method="bilinear")
    # polanalyser: OpenCV's Bayer interpolation per polarizer channel, then Stokes
    i0, i45, i90, i135 = pa.demosaicing(raw, pa.COLOR_PolarMono)
    stokes = pa.calcStokes([i0, i45, i90, i135], np.deg2rad([0, 45, 90, 135]))
    theirs = np.rad2deg(pa.cvtStokesToAoLP(stokes)) % 180.0
    inner = (slice(4, -4), slice(4, -4))  # both treat the border differently
    sky = f["truth_dolp"][inner] > 0.05
    rows = []
    for name, aolp in [("psns bilinear", ours["aolp"]), ("polanalyser (OpenCV bilinear)", theirs)]:
        e = angle_error(aolp[inner], truth[inner])[sky]
        rows.append((name, float(np.median(e)), float(np.percentile(e, 99))))
    between = angle_error(ours["aolp"][inner], theirs[inner])[sky]
    return rows, float(np.median(between))


if __name__ == "__main__":
    ap = argparse.ArgumentParser()
    ap.add_argument("--width", type=int, default=612)
    ap.add_argument("--height", type=int, default=512)
    a = ap.parse_args()
    rows, between = compare(a.width, a.height)
    print("method,median_aolp_error_deg,p99_aolp_error_deg")
    for name, med, p99 in rows:
        print(f"{name},{med:.4f},{p99:.4f}")
    print(f"# median |psns - polanalyser| AoLP: {between:.4f} deg")
