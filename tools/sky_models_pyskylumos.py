#!/usr/bin/env python3
"""Compare `psns sky --model M` with pyskylumos 0.1.3's own implementation of M.

Usage: sky_models_pyskylumos.py PSNS_BINARY [--seed N] [--suns N] [--directions N]

For every model (rayleigh, depolarized-rayleigh, berry, pan, queen, asymmetric) it draws random
suns and random directions above the horizon inside the model's valid range, at equal parameters
(neutral-point distances, dop_max, depolarization ratio), runs `psns sky` and pyskylumos on the
same directions and prints, per model, the largest DOP and AOP differences. AOP is pyskylumos's
own angle: its world-chart angle (from north toward east) against psns's `aop_north_deg`, and for
`pan` (Pan's eq. (23), referenced to the local meridian) against `aop_meridian_deg`. Directions
where the DOP is below 1e-6 (a neutral point, the sun) have no AOP and are left out of the AOP
comparison.

Then, where pyskylumos turns every AOP by 90 degrees (a root of its quartic past the nadir: berry
with the sun closer to the zenith than the neutral-point distance, asymmetric with the sun closer
than the fourth point's distance), it checks that the two differ by 90 degrees there and that
psns's AOP is continuous across the threshold.

The last line is `N passed, M failed` over the checks; the exit status is 1 if any failed.

pyskylumos 0.1.3 declares Python >= 3.12. Its only 3.12-only code is the `type X = ...`
statements of `pyskylumos/_types.py`; on Python 3.11 this script registers an equivalent
`pyskylumos._types` module (the same aliases as plain assignments) before importing the package,
so the package's own model code runs unchanged. tools/test installs it with
`--no-deps --ignore-requires-python` after its dependencies (numpy, astropy).
"""

import argparse
import csv
import io
import subprocess
import sys
import types
import warnings

import numpy as np

if sys.version_info < (3, 12):
    from collections.abc import Callable
    from typing import Any

    from numpy.typing import NDArray

    _shim = types.ModuleType("pyskylumos._types")
    _shim.FloatArray = NDArray[np.float64]
    _shim.SensorArray = NDArray[np.float32]
    _shim.RealArray = NDArray[np.floating[Any]]
    _shim.ComplexArray = NDArray[np.complex128]
    _shim.BoolArray = NDArray[np.bool_]
    _shim.ProjectionHook = Callable[..., NDArray[np.float64]]
    _shim.ParameterNames = tuple[str, ...]
    sys.modules["pyskylumos._types"] = _shim

import astropy.units as u  # noqa: E402
from astropy.coordinates import AltAz, EarthLocation, SkyCoord  # noqa: E402
from astropy.time import Time  # noqa: E402
from astropy.utils import iers  # noqa: E402

import pyskylumos  # noqa: E402
from pyskylumos.sky_models import (  # noqa: E402
    AsymmetricQuartic,
    Berry,
    DepolarizedRayleigh,
    Pan,
    QuEEN,
    Rayleigh,
)

iers.conf.auto_download = False
warnings.simplefilter("ignore")

TIME = Time("2024-06-01T12:00:00")
PLACE = EarthLocation(lat=45 * u.deg, lon=7 * u.deg, height=0 * u.m)
TOL_DOP = 1e-5
TOL_AOP = {"asymmetric": 1e-3}
TOL_AOP_DEFAULT = 1e-4


def axial(a, b):
    """Axial difference of angles in degrees, in [0, 90]."""
    d = np.mod(np.asarray(a) - np.asarray(b), 180.0)
    return np.minimum(d, 180.0 - d)


def psns_sky(binary, sun_alt, sun_az, alt, az, opts):
    """`psns sky` for directions (altitude, azimuth in degrees): (dop, aop_meridian, aop_north)."""
    lines = ["zenith_deg,azimuth_deg"]
    lines += [f"{90.0 - float(a)!r},{float(z)!r}" for a, z in zip(alt.ravel(), az.ravel())]
    cmd = [
        binary,
        "sky",
        "--sun-altitude",
        repr(float(sun_alt)),
        "--sun-azimuth",
        repr(float(sun_az)),
        *opts,
    ]
    out = subprocess.run(
        cmd, input="\n".join(lines) + "\n", capture_output=True, text=True, check=False
    )
    if out.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)}: {out.stderr.strip()}")
    rows = list(csv.DictReader(io.StringIO(out.stdout)))
    col = lambda k: np.array([float(r[k]) for r in rows])  # noqa: E731
    return col("dop"), col("aop_meridian_deg"), col("aop_north_deg")


def sky_model(cls, alt, az, **kw):
    """A pyskylumos model over the directions (one time, 1 x n grid)."""
    return cls(
        times=TIME,
        observation_location=PLACE,
        azimuths=az.reshape(1, -1),
        altitudes=alt.reshape(1, -1),
        **kw,
    )


def pysky(model, sun_alt, sun_az):
    """pyskylumos's (dop, aop degrees) for an explicit sun."""
    sun = SkyCoord(
        alt=sun_alt * u.deg, az=sun_az * u.deg, frame=AltAz(obstime=TIME, location=PLACE)
    )
    out = model.simulate_sky(cie_sky_type=12, sun_position=sun)
    return np.asarray(out[0]).ravel(), np.degrees(np.asarray(out[1]).ravel())


def berry_class(delta_deg):
    """pyskylumos's Berry with both neutral points `delta_deg` from the sun (its class constant
    is the pairwise separation, fixed at 30 degrees in the package)."""
    return type("BerryDelta", (Berry,), {"NEUTRAL_POINT_SEPARATION_DEG": 2.0 * delta_deg})


def directions(rng, n):
    """Random directions uniform on the sky above 1 degree of altitude."""
    alt = np.degrees(np.arcsin(rng.uniform(np.sin(np.radians(1.0)), 1.0, n)))
    az = rng.uniform(0.0, 360.0, n)
    return alt, az


def pan_brewster(e):
    return 37.34 + 0.49 * e if e <= 27.0 else 56.84 - 0.25 * e


def cases(rng, n_suns):
    """(model, sun altitude, sun azimuth, psns options, pyskylumos class, its keywords, AOP
    column) for random suns inside each model's valid range."""
    out = []
    for _ in range(n_suns):
        az = rng.uniform(0.0, 360.0)
        e = rng.uniform(0.5, 89.5)
        out.append(("rayleigh", e, az, ["--model", "rayleigh"], Rayleigh, {}, "north"))
        d = float(rng.choice([0.0, 0.0279, rng.uniform(0.0, 0.5)]))
        out.append(
            (
                "depolarized-rayleigh",
                e,
                az,
                ["--model", "depolarized-rayleigh", "--depolarization-ratio", repr(d)],
                DepolarizedRayleigh,
                {"depolarization_ratio": d},
                "north",
            )
        )
        # berry: pyskylumos flips with the sun closer to the zenith than delta
        delta = rng.uniform(5.0, 40.0)
        eb = rng.uniform(0.5, 89.0 - delta)
        out.append(
            (
                "berry",
                eb,
                az,
                ["--model", "berry", "--neutral-distance", repr(delta)],
                berry_class(delta),
                {},
                "north",
            )
        )
        ep = rng.uniform(0.0, 64.0)
        out.append(
            ("pan", ep, az, ["--model", "pan"], Pan, {"out_of_range": "ignore"}, "meridian")
        )
        dm = rng.uniform(0.3, 1.0)
        out.append(
            (
                "queen",
                ep,
                az,
                ["--model", "queen", "--dop-max", repr(dm)],
                QuEEN,
                {"dop_max": dm, "out_of_range": "ignore"},
                "north",
            )
        )
        # asymmetric, default distances (Arago and fourth at the Brewster distance): pyskylumos
        # flips above 44.2 degrees of elevation, where the fourth point passes the nadir
        ea = rng.uniform(0.0, 44.0)
        out.append(
            (
                "asymmetric",
                ea,
                az,
                ["--model", "asymmetric", "--dop-max", repr(dm)],
                AsymmetricQuartic,
                {"dop_max": dm, "out_of_range": "ignore"},
                "north",
            )
        )
        # asymmetric with its own Arago and fourth distances, sun below the fourth's threshold
        arago = rng.uniform(5.0, 60.0)
        fourth = rng.uniform(5.0, 60.0)
        ea = rng.uniform(0.0, min(64.0, 89.0 - fourth))
        out.append(
            (
                "asymmetric",
                ea,
                az,
                ["--model", "asymmetric", "--arago", repr(arago), "--fourth", repr(fourth)],
                AsymmetricQuartic,
                {"arago_offset": arago, "fourth_offset": fourth, "out_of_range": "ignore"},
                "north",
            )
        )
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("psns")
    ap.add_argument("--seed", type=int, default=31)
    ap.add_argument("--suns", type=int, default=12)
    ap.add_argument("--directions", type=int, default=300)
    a = ap.parse_args()
    rng = np.random.default_rng(a.seed)
    print(f"pyskylumos {pyskylumos.__version__} on Python {sys.version.split()[0]}")
    worst = {}
    passed = failed = 0

    def check(ok, what):
        nonlocal passed, failed
        if ok:
            passed += 1
        else:
            failed += 1
            print(f"FAILED: {what}")

    for name, e, az, opts, cls, kw, ref in cases(rng, a.suns):
        alt, daz = directions(rng, a.directions)
        dop_p, aop_m, aop_n = psns_sky(a.psns, e, az, alt, daz, opts)
        dop_s, aop_s = pysky(sky_model(cls, alt, daz, **kw), e, az)
        aop_p = aop_m if ref == "meridian" else aop_n
        pol = (dop_s > 1e-6) & np.isfinite(aop_s)
        ddop = float(np.max(np.abs(dop_p - dop_s)))
        daop = float(np.max(axial(aop_p[pol], aop_s[pol]))) if pol.any() else 0.0
        w = worst.setdefault(name, [0.0, 0.0, 0, 0])
        w[0], w[1] = max(w[0], ddop), max(w[1], daop)
        w[2] += 1
        w[3] += len(alt)
        tol = TOL_AOP.get(name, TOL_AOP_DEFAULT)
        check(
            ddop <= TOL_DOP and daop <= tol,
            f"{name} sun ({e:.4f}, {az:.4f}) {' '.join(opts)}: max |dDOP| {ddop:.3g}, "
            f"max |dAOP| {daop:.3g} deg",
        )
    print("model,suns,directions,max_abs_ddop,max_abs_daop_deg,tol_dop,tol_aop_deg")
    for name, (dd, da, ns, nd) in worst.items():
        tol = TOL_AOP.get(name, TOL_AOP_DEFAULT)
        print(f"{name},{ns},{nd},{dd:.3e},{da:.3e},{TOL_DOP:g},{tol:g}")

    # pyskylumos's own flips: 90 degrees off on the far side, psns continuous across
    flips = []
    for k in range(4):
        delta = 10.0 + 7.0 * k
        flips.append(("berry", 90.0 - delta, ["--model", "berry", "--neutral-distance",
                      repr(delta)], berry_class(delta), {}))
    # default asymmetric: fourth point at the Brewster distance 56.84 - 0.25 e passes the
    # nadir where 90 - e = 56.84 - 0.25 e, e = 44.2133
    flips.append(("asymmetric", (90.0 - 56.84) / 0.75, ["--model", "asymmetric"],
                  AsymmetricQuartic, {"out_of_range": "ignore"}))
    flips.append(("asymmetric", 90.0 - 30.0, ["--model", "asymmetric", "--fourth", "30"],
                  AsymmetricQuartic, {"fourth_offset": 30.0, "out_of_range": "ignore"}))
    print("flip,threshold_elevation_deg,median_daop_below,median_daop_above,psns_median_step_deg")
    for name, thr, opts, cls, kw in flips:
        az = rng.uniform(0.0, 360.0)
        alt, daz = directions(rng, a.directions)
        res = []
        for e in (thr - 0.05, thr + 0.05):
            dop_p, _, aop_n = psns_sky(a.psns, e, az, alt, daz, opts)
            dop_s, aop_s = pysky(sky_model(cls, alt, daz, **kw), e, az)
            pol = (dop_s > 1e-3) & (dop_p > 1e-3)
            res.append((aop_n, float(np.median(axial(aop_n[pol], aop_s[pol]))), pol))
        (a0, below, p0), (a1, above, p1) = res
        both = p0 & p1
        step = float(np.median(axial(a0[both], a1[both])))
        print(f"{name} {' '.join(opts[2:])},{thr:.4f},{below:.4g},{above:.4g},{step:.4g}")
        check(below < 1e-6, f"{name}: pyskylumos and psns agree below the flip ({below})")
        check(abs(above - 90.0) < 1e-6, f"{name}: pyskylumos is 90 deg off above ({above})")
        check(step < 0.5, f"{name}: psns continuous across {thr:.3f} deg ({step} deg)")
    print(f"{passed} passed, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
