#!/usr/bin/env python3
"""Fits the binade polynomials of src/sensor/normal.rs and prints them as its NORMAL_POLY table.

g(t) = Phi^-1(1 - t/2) (Python's statistics.NormalDist, Wichura's AS241, ~1e-16) is fitted on
each binade t in [2^-(j+1), 2^-j), j = 0..15, as a degree-6 polynomial in y = mantissa - 1.5 by
least squares on 200 Chebyshev nodes, rounded to f32. The error is then measured with f32
Horner steps (each an exactly rounded fused multiply-add, as in the kernels) on 4000 points
per binade and printed to stderr. Needs numpy. Usage: tools/fit_normal_binades.py > table.rs
"""
import sys
from statistics import NormalDist

import numpy as np

DEG = 6
NODES = 200
INV = NormalDist().inv_cdf


def g(t):
    return np.array([INV(1.0 - x / 2.0) for x in np.atleast_1d(t)])


def horner_f32(coef, y):
    p = np.float32(coef[0])
    for c in coef[1:]:
        # a fused multiply-add: the product of two f32 values is exact in f64, the sum is rounded
        # to f64 and then to f32 (twice, so the printed error may differ from the kernels' by
        # half an f32 ulp; the Rust tests check the table itself)
        p = np.float32(np.float64(p) * np.float64(y) + np.float64(np.float32(c)))
    return p


def main():
    table = [[0.0] * 16 for _ in range(DEG + 1)]
    worst = 0.0
    y_nodes = 0.5 * np.cos(np.pi * (np.arange(NODES) + 0.5) / NODES)
    for j in range(16):
        lo = 2.0 ** -(j + 1)
        coef = [float(np.float32(c)) for c in np.polyfit(y_nodes, g((y_nodes + 1.5) * lo), DEG)]
        p = (149 - j) & 15  # exponent field of 2^23 t, mod 16
        for d in range(DEG + 1):
            table[d][p] = coef[d]
        t = np.linspace(lo, 2 * lo, 4001)[:-1]
        ys = (t / lo - 1.5).astype(np.float32)
        err = np.max(np.abs(np.array([horner_f32(coef, y) for y in ys], dtype=np.float64) - g(t)))
        worst = max(worst, err)
        print(f"binade {j:2}: t in [2^-{j + 1}, 2^-{j}), max |error| {err:.2e}", file=sys.stderr)
    print(f"worst {worst:.2e}", file=sys.stderr)
    print(f"const NORMAL_POLY: [[f32; 16]; {DEG + 1}] = [")
    for row in table:
        print("    [" + ", ".join(str(np.float32(v)) for v in row) + "],")
    print("];")


if __name__ == "__main__":
    main()
