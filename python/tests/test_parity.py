"""The Python functions give what the CLI gives for the same options, bit for bit."""

import io
import re
import numpy as np
import pytest

import psns
from conftest import cli_message, read_png_gray, run

SMALL = dict(width=128, height=96)
SCENE = dict(sun_zenith=40, sun_azimuth=120, turbidity=3, wavelength=500, yaw=10, pitch=3, roll=-2)


def cli_args(opts):
    out = []
    for k, v in opts.items():
        out += [f"--{k.replace('_', '-')}", str(v)]
    return out


def test_render_matches_cli(psns_bin, tmp_path):
    opts = dict(SMALL, **SCENE)
    run(psns_bin, "render", *cli_args(opts), "--out", tmp_path / "o")
    py = psns.render(**opts)
    for k in ("li", "dop", "aop"):
        want = np.load(tmp_path / "o" / f"{k}.npy")
        assert py[k].dtype == np.float32 and py[k].shape == (96, 128)
        assert np.array_equal(py[k], want, equal_nan=True), k
    assert np.array_equal(py["class"], np.load(tmp_path / "o" / "class.npy"))


def test_render_in_a_world_matches_cli(psns_bin, tmp_path):
    opts = dict(SMALL, projection="equidistant", focal_length=1.8, pixel_pitch=55.2,
                canyon="20,6,30", cloud_cover=0.3, seed=5)
    run(psns_bin, "render", *cli_args(opts), "--out", tmp_path / "o")
    py = psns.render(**opts)
    for k in ("li", "dop", "aop", "class"):
        assert np.array_equal(py[k], np.load(tmp_path / "o" / f"{k}.npy"), equal_nan=True), k
    # walls and clouds are in the picture
    assert (py["class"] == 3).mean() > 0.1 and (py["class"] == 2).mean() > 0.01


def model_names(psns_bin):
    """The polarization models, in the library's table's order: the values the CLI allows."""
    r = run(psns_bin, "render", "--model", "nope", ok=False)
    m = re.search(r"\[possible values: ([^\]]+)\]", r.stderr)
    assert m, r.stderr
    return [n.strip() for n in m.group(1).split(",")]


def test_every_sky_model_matches_cli(psns_bin, tmp_path):
    names = model_names(psns_bin)
    assert "wang" in names and "rayleigh" in names, names
    seen = {}
    for m in names:
        opts = dict(SMALL, **SCENE, model=m)
        run(psns_bin, "render", *cli_args(opts), "--out", tmp_path / m)
        py = psns.render(**opts)
        for k in ("li", "dop", "aop"):
            want = np.load(tmp_path / m / f"{k}.npy")
            assert np.array_equal(py[k], want, equal_nan=True), (m, k)
        key = py["dop"].tobytes() + py["aop"].tobytes()
        assert key not in seen, f"{m} gives the sky of {seen.get(key)}"
        seen[key] = m


@pytest.mark.parametrize("bits", [12, 8])
def test_render_raw_matches_cli_raw_png(psns_bin, tmp_path, bits):
    opts = dict(SMALL, **SCENE, seed=5, frame_index=2, bit_depth=bits, gain_db=6)
    run(psns_bin, "render", "--raw", *cli_args(opts), "--out", tmp_path / "o")
    py = psns.render_raw(**opts)
    want = read_png_gray(tmp_path / "o" / "raw.png")
    assert py["raw"].dtype == (np.uint8 if bits == 8 else np.uint16)
    assert np.array_equal(py["raw"], want)
    assert py["raw"].max() > 0
    for k in ("s0", "s1", "s2", "dolp", "aolp"):
        assert np.array_equal(py[f"truth_{k}"], np.load(tmp_path / "o" / f"truth_{k}.npy")), k
    # a different seed is a different frame: the comparison above can fail
    other = psns.render_raw(**dict(opts, seed=6))["raw"]
    assert not np.array_equal(other, want)


@pytest.mark.parametrize("method", ["bilinear", "newton", "superpixel"])
def test_demosaic_matches_cli(psns_bin, tmp_path, method):
    raw = psns.render_raw(**SMALL, seed=1)["raw"]
    run(psns_bin, "render", "--raw", "--width", 128, "--height", 96, "--seed", 1, "--out", tmp_path / "r")
    run(psns_bin, "demosaic", tmp_path / "r" / "raw.png", "--method", method, "--out", tmp_path / "d")
    py = psns.demosaic(raw, method=method)
    for k in ("s0", "s1", "s2", "dolp", "aolp"):
        assert np.array_equal(py[k], np.load(tmp_path / "d" / f"{k}.npy"), equal_nan=True), k


def test_demosaic_debias_and_black_level():
    raw = psns.render_raw(**SMALL, seed=1, black_level=40)["raw"]
    a = psns.demosaic(raw, black_level=40, dolp_debias=3.0)
    b = psns.demosaic(raw)
    assert "dolp_debiased" in a
    assert np.all(a["dolp_debiased"] <= a["dolp"] + 1e-6)
    # the black level is subtracted: S0 drops by 2 x 40 (S0 = I0 + I90)
    assert abs(float(np.mean(b["s0"] - a["s0"])) - 80.0) < 1e-2


def test_heading_matches_cli(psns_bin, tmp_path):
    opts = dict(width=612, height=512, frame="enu", yaw=33, pitch=2, roll=-1, seed=4)
    run(psns_bin, "render", "--raw", *cli_args(opts), "--out", tmp_path / "o")
    raw = read_png_gray(tmp_path / "o" / "raw.png")
    tilt = dict(width=612, height=512, pitch=2, roll=-1, sun_zenith=50, sun_azimuth=200)
    r = run(psns_bin, "heading", tmp_path / "o" / "raw.png", *cli_args(tilt))
    header, row = r.stdout.strip().splitlines()
    want = dict(zip(header.split(","), row.split(",")))
    py = psns.heading(raw, **tilt)
    assert f"{py['yaw_deg']:.4f}" == want["yaw_deg"]
    assert f"{py['confidence']:.4f}" == want["confidence"]
    assert str(py["pixels"]) == want["pixels"]
    assert f"{py['residual_deg']:.4f}" == want["residual_deg"]
    assert f"{py['sky_fraction']:.4f}" == want["sky_fraction"]
    assert abs(py["yaw_deg"] - 33) < 0.5
    # the sky mask: none uses at least what the found one keeps
    none = psns.heading(raw, **tilt, mask="none")
    assert none["sky_fraction"] >= py["sky_fraction"] > 0.8, (none, py)


def test_heading_residual_flags_wrong_inputs():
    # the attitude and sun given explicitly: a level camera at ENU yaw 30, the sun 40 deg up
    sun = dict(sun_zenith=50, sun_azimuth=200)
    geom = dict(width=612, height=512, pixel_pitch=13.8)
    raw = psns.render_raw(**geom, **sun, frame="enu", yaw=30, pitch=0, roll=0,
                          auto_exposure=True, seed=2)["raw"]
    right = psns.heading(raw, **geom, **sun, pitch=0, roll=0)
    assert abs(right["yaw_deg"] - 30) < 0.1 and right["confidence"] > 0.85, right
    assert 0 < right["residual_deg"] < 3, right
    wrong = psns.heading(raw, **geom, **sun, pitch=0, roll=40)
    assert abs(wrong["yaw_deg"] - 30) > 5, wrong  # the roll moves the yaw
    assert wrong["confidence"] < 0.5 and wrong["residual_deg"] > 2 * right["residual_deg"], wrong
    # the sun at the zenith: no yaw, as for too few pixels
    raw = psns.render_raw(**geom, sun_zenith=0, sun_azimuth=200, frame="enu", yaw=30,
                          auto_exposure=True, seed=2)["raw"]
    z = psns.heading(raw, **geom, sun_zenith=0, sun_azimuth=200)
    assert np.isnan(z["yaw_deg"]) and z["confidence"] == 0 and np.isnan(z["residual_deg"]), z


@pytest.mark.parametrize(
    "model",
    [
        {},
        dict(model="queen", dop_max=0.8),
        dict(model="asymmetric", arago=20, fourth=30),
        dict(model="depolarized-rayleigh", depolarization_ratio=0.1),
        dict(model="pan", radiance="cie:12"),
        dict(model="berry", neutral_distance=15),
    ],
)
def test_sky_matches_cli(psns_bin, model):
    z = np.array([[0.0, 10.0, 45.0], [80.0, 89.5, 120.0]])
    a = np.array([[0.0, 90.0, 200.0], [359.0, 17.5, 3.0]])
    opts = dict(sun_zenith=60, sun_azimuth=100, turbidity=5, **model)
    text = "zenith_deg,azimuth_deg\n" + "".join(f"{zz},{aa}\n" for zz, aa in zip(z.ravel(), a.ravel()))
    r = run(psns_bin, "sky", *cli_args(opts), input=text)
    rows = np.loadtxt(io.StringIO(r.stdout), delimiter=",", skiprows=1)
    py = psns.sky(z, a, **opts)
    assert py["dop"].shape == (2, 3)
    cols = ["gamma_deg", "radiance", "dop", "aop_meridian_deg", "aop_north_deg"]
    for k, name in enumerate(cols):
        # the CLI prints 9 (6 for AOP) significant decimals
        tol = 1e-6 if "aop" in name else 1e-9 * max(1.0, np.abs(rows[:, 2 + k]).max())
        assert np.allclose(py[name].ravel(), rows[:, 2 + k], rtol=1e-8, atol=tol), name
    assert py["radiance"][1, 2] == 0.0  # below the horizon


@pytest.mark.parametrize(
    "cmd, opts, call",
    [
        (["render"], dict(sun_zenith=95), lambda: psns.render(sun_zenith=95)),
        (["render"], dict(turbidity=12), lambda: psns.render(turbidity=12)),
        (["render"], dict(sun_zenith="abc"), lambda: psns.render(sun_zenith="abc")),
        (["render"], dict(width=0), lambda: psns.render(width=0)),
        (["render"], dict(preset="camera"), lambda: psns.render(preset="camera")),
        (["render"], dict(dop_model="nope"), lambda: psns.render(dop_model="nope")),
        (["render"], dict(model="nope"), lambda: psns.render(model="nope")),
        (
            ["render"],
            dict(model="pan", babinet=10, brewster=12),
            lambda: psns.render(model="pan", babinet=10, brewster=12),
        ),
        (["render"], dict(radiance="cie:0"), lambda: psns.render(radiance="cie:0")),
        (["render", "--raw"], dict(bit_depth=9), lambda: psns.render_raw(bit_depth=9)),
        (["render", "--raw"], dict(preset="foo"), lambda: psns.Camera(preset="foo")),
        (["render", "--raw"], dict(sky_grid=0), lambda: psns.render_raw(sky_grid=0)),
        (["render"], dict(width=640.0), lambda: psns.render(width=640.0)),
        (["render", "--raw"], dict(bit_depth=8.5), lambda: psns.render_raw(bit_depth=8.5)),
    ],
)
def test_errors_are_the_cli_messages(psns_bin, tmp_path, cmd, opts, call):
    r = run(psns_bin, *cmd, *cli_args(opts), "--out", tmp_path / "o", ok=False)
    assert r.returncode == 2
    with pytest.raises(ValueError) as e:
        call()
    assert str(e.value) == cli_message(r.stderr)


def test_unknown_keyword_is_a_value_error():
    with pytest.raises(ValueError, match="unexpected argument sun_zenit= "):
        psns.render(sun_zenit=40)
    with pytest.raises(ValueError, match="raw must be a 2-D numpy array"):
        psns.demosaic(np.zeros((8, 8), np.float32))
    with pytest.raises(ValueError, match="smallest|at least|8"):
        psns.demosaic(np.zeros((4, 4), np.uint16))


def test_errors_name_the_keyword_argument():
    # width=640.0 is not an integer, said with the keyword's name (not "invalid digit", not --width)
    with pytest.raises(ValueError) as e:
        psns.render(width=640.0)
    assert str(e.value) == "invalid value '640.0' for width=: '640.0' is not an integer"
    with pytest.raises(ValueError, match="for sun_zenith=: 'abc' is not a number"):
        psns.render(sun_zenith="abc")
    with pytest.raises(ValueError, match="quaternion= cannot be used with yaw="):
        psns.render(quaternion=(1, 0, 0, 0), yaw=3)


def test_camera_with_a_quaternion_refuses_angles():
    # the CLI refuses --yaw with --quaternion; Camera.frame does too (no silent zero pitch/roll)
    cam = psns.Camera(width=32, height=24, quaternion=(1, 0, 0, 0))
    for kw in ("yaw", "pitch", "roll"):
        with pytest.raises(ValueError, match=f"{kw}= cannot be used with quaternion="):
            cam.frame(**{kw: 30})
    assert cam.frame().shape == (24, 32)
