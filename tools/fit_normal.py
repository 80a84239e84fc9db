#!/usr/bin/env python3
"""Fits the polynomials of src/sensor/normal.rs and prints its NORMAL8, LN and TAIL tables.

z = Phi^-1(u) for u = (2k + 1)/2^24 (k the top 23 bits of a random word), with x = 2u - 1 and
t = 1 - |x| = 2 min(u, 1 - u), both exact in f32; z = sign(x) g(t), g(t) = Phi^-1(1 - t/2):
  - t >= 2^-8 (99.6 % of draws): g is a degree-4 polynomial in y = mantissa - 1.5 of t's binade
    [2^-(j+1), 2^-j), j = 0..7 (NORMAL8, indexed by the f32 exponent of 2^23 t modulo 8), fitted
    by least squares on 300 Chebyshev nodes;
  - t < 2^-8: g = Q(sqrt(w)), w = -ln(t (2 - t)), Q of degree 6 (TAIL), with ln y = e ln 2 +
    f R(f), y = 2^e (1 + f), 1 + f in [sqrt(1/2), sqrt(2)), R of degree 6 (LN), down to the
    lattice's smallest t = 2^-23.
The reference is Python's statistics.NormalDist (Wichura's AS241, ~1e-16). The error of the f32
evaluation (each fused multiply-add emulated in f64, then rounded to f32) is measured on the
whole u < 1/2 half of the lattice (z is odd in x), and monotonicity checked there; both are
printed to stderr. Needs numpy. Usage: tools/fit_normal.py > table.rs
"""
import sys
from statistics import NormalDist

import numpy as np

DEG8, DL, DT = 4, 6, 6
TAIL_BELOW = 1 << 15  # 2^23 t below this takes the tail
INV = NormalDist().inv_cdf
F = np.float32


def g_of_t(t):
    return np.array([INV(1.0 - x / 2.0) for x in np.atleast_1d(t)])


def cheb(a, b, n):
    return a + (b - a) * (np.cos(np.pi * (np.arange(n) + 0.5) / n) + 1) / 2


def fit():
    table = np.zeros((DEG8 + 1, 8))
    y = cheb(-0.5, 0.5, 300)
    for j in range(8):
        lo = 2.0 ** -(j + 1)
        c = np.polyfit(y, g_of_t((y + 1.5) * lo), DEG8)
        table[:, (149 - j) % 8] = c  # 149 - j: f32 exponent field of 2^23 t in binade j
    f = cheb(np.sqrt(0.5) - 1, np.sqrt(2) - 1, 800)
    a = np.vstack([f**k for k in range(1, DL + 2)]).T
    ln = np.linalg.lstsq(a, np.log1p(f), rcond=None)[0][::-1]
    tmin, tlo = TAIL_BELOW / 2.0**23, 2.0**-23
    s = cheb(np.sqrt(-np.log(tmin * (2 - tmin))), np.sqrt(-np.log(tlo * (2 - tlo))), 800)
    x = np.sqrt(-np.expm1(-s * s))
    tail = np.polyfit(s, g_of_t(np.exp(-s * s) / (1 + x)), DT)
    return table.astype(F), ln.astype(F), tail.astype(F)


def fma(a, b, c):
    return (a.astype(np.float64) * b + c).astype(F)


def horner(coef, x):
    p = np.full_like(x, coef[0])
    for c in coef[1:]:
        p = fma(p, x, F(c))
    return p


def evaluate(table, ln, tail, k):
    """The kernels' f32 arithmetic: g(t) for the lattice points k."""
    v = 2 * k.astype(np.int64) + 1 - (1 << 23)
    t = (1 << 23) - np.abs(v)
    tf = t.astype(F)
    bits = tf.view(np.uint32)
    p = (bits >> 23) & 7
    y = ((bits & 0x7FFFFF) | 0x3F800000).view(F) - F(1.5)
    r = table[0][p]
    for row in table[1:]:
        r = fma(r, y, row[p])
    tt = tf * F(2.0**-23)
    yy = tt * (F(2.0) - tt)
    b = yy.view(np.uint32) + np.uint32(0x3F800000 - 0x3F3504F3)
    e = ((b >> 23).astype(np.int32) - 127).astype(F)
    f = ((b & 0x7FFFFF) + 0x3F3504F3).astype(np.uint32).view(F) - F(1.0)
    w = -fma(e, F(np.log(2.0)), horner(ln, f) * f)
    q = horner(tail, np.sqrt(np.maximum(w, 0)))
    return np.where(t >= TAIL_BELOW, r, q)


def f32_literal(v):
    """The shortest decimal that reads back as the same f32 (what clippy's excessive_precision asks)."""
    x = np.float32(v)
    for digits in range(1, 10):
        text = f"{float(x):.{digits}g}"
        if np.float32(text) == x:
            return text if ("." in text or "e" in text) else text + ".0"
    raise ValueError(v)


def main():
    table, ln, tail = fit()
    k = np.arange(1 << 22, dtype=np.int64)  # u < 1/2: z = -g(t)
    z = -evaluate(table, ln, tail, k)
    sample = np.arange(0, len(k), 31)
    ref = np.array([INV(u) for u in (2 * k[sample] + 1) / 2.0**24])
    err = np.abs(z[sample] - ref)
    print(f"max |error| {err.max():.2e} (every 31st point of the u < 1/2 lattice)", file=sys.stderr)
    print(f"non-decreasing in u: {bool(np.all(np.diff(z) >= 0))}", file=sys.stderr)
    print(f"const NORMAL8: [[f32; 8]; {DEG8 + 1}] = [")
    for row in table:
        print("    [" + ", ".join(f32_literal(v) for v in row) + "],")
    print("];")
    for name, c in (("LN", ln), ("TAIL", tail)):
        print(f"const {name}: [f32; {len(c)}] = [" + ", ".join(f32_literal(v) for v in c) + "];")


if __name__ == "__main__":
    main()
