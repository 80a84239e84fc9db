"""Camera.frame against psns stream, open_stream against psns verify, zero-copy results."""

import os
import threading
import time
import warnings

import numpy as np
import pytest

import psns
from conftest import run

W, H = 160, 120
SUN = dict(sun_zenith=35, sun_azimuth=140)
POSES = [(0.0, 10.0, 1.0, -2.0), (0.1, 55.0, -3.0, 0.5), (0.2, 300.0, 0.0, 4.0)]


def stream_file(psns_bin, path, extra=()):
    traj = "t_s,yaw_deg,pitch_deg,roll_deg\n" + "".join(f"{t},{y},{p},{r}\n" for t, y, p, r in POSES)
    run(
        psns_bin, "stream", "--width", W, "--height", H, "--seed", 9,
        "--sun-zenith", SUN["sun_zenith"], "--sun-azimuth", SUN["sun_azimuth"],
        "--trajectory", "-", "--out", path, *extra, input=traj,
    )


def test_camera_frames_are_the_stream_frames(psns_bin, tmp_path):
    path = tmp_path / "s.psns"
    stream_file(psns_bin, path)
    cam = psns.Camera(width=W, height=H, seed=9, frame="enu", **SUN)
    got = list(psns.open_stream(path))
    assert [i for i, _, _ in got] == [0, 1, 2]
    for (i, meta, frame), (_, y, p, r) in zip(got, POSES):
        mine = cam.frame(yaw=y, pitch=p, roll=r, frame_index=i)
        assert mine.dtype == np.uint16 and mine.shape == (H, W)
        assert np.array_equal(mine, frame), i
        assert meta["index"] == i and meta["exposure_us"] > 0
    # the same pose with another index is another noise draw
    assert not np.array_equal(cam.frame(yaw=10, pitch=1, roll=-2, frame_index=5), got[0][2])


def test_camera_meta_is_the_stream_frame_header(psns_bin, tmp_path):
    """meta is the frame record the stream's header derives from, class fractions included."""
    # a fisheye wide enough to see the walls from the zenith
    world = ("--canyon", "20,6,30", "--projection", "equidistant", "--focal-length", "0.4",
             "--pixel-pitch", "13.8")
    path = tmp_path / "w.psns"
    stream_file(psns_bin, path, world)
    cam = psns.Camera(width=W, height=H, seed=9, frame="enu", canyon="20,6,30",
                      projection="equidistant", focal_length=0.4, pixel_pitch=13.8, **SUN)
    for (i, head, frame), (_, y, p, r) in zip(psns.open_stream(path), POSES):
        mine, m = cam.frame(yaw=y, pitch=p, roll=r, frame_index=i, meta=True)
        assert np.array_equal(mine, frame), i
        assert m["frame_index"] == head["index"] == i
        for k in ("exposure_us", "gain_db", "sun_azimuth_deg", "sun_camera", "attitude_wxyz",
                  "saturated"):
            assert m[k] == head[k], (k, m[k], head[k])
        assert head["flags"] & (1 << 8)
        got = np.array(head["class_fractions"], dtype=np.float32)
        assert np.array_equal(np.array(m["class_fractions"], dtype=np.float32), got)
        assert abs(sum(m["class_fractions"]) - 1) < 1e-9 and m["class_fractions"][3] > 0.05
    _, m = psns.Camera(width=W, height=H).frame(meta=True)
    assert m["class_fractions"] is None


def test_camera_defaults_and_meta():
    cam = psns.Camera(width=64, height=48, seed=1, frame_index=7)
    a, m = cam.frame(meta=True)
    assert m["frame_index"] == 7 and (m["sun_zenith_deg"], m["sun_azimuth_deg"]) == (50.0, 200.0)
    b, m2 = cam.frame(meta=True)
    assert m2["frame_index"] == 8
    assert np.array_equal(cam.frame(frame_index=7), a)
    with pytest.raises(ValueError, match="below the horizon"):
        cam.frame(sun_zenith=95)
    with pytest.raises(ValueError, match="yaw = NaN is out of range"):
        cam.frame(yaw=float("nan"))
    assert psns.Camera(width=64, height=48, bit_depth=8).frame().dtype == np.uint8
    # a negative or too large index is a value error with the CLI's range, not OverflowError
    for bad in (-1, 2**64):
        with pytest.raises(ValueError, match=f"frame_index = {bad} is out of range"):
            cam.frame(frame_index=bad)
    with pytest.raises(TypeError):
        cam.frame(frame_index=1.5)


def test_results_take_over_the_rust_buffer():
    """Documented zero-copy: the array's memory belongs to a Rust container, not to numpy."""
    cam = psns.Camera(width=64, height=48)
    for a in [cam.frame(), psns.render(width=64, height=48)["dop"], psns.demosaic(cam.frame())["s0"]]:
        assert not a.flags.owndata and a.base is not None
        assert type(a.base).__name__ == "PySliceContainer"
        assert a.flags.c_contiguous and a.flags.writeable


def test_camera_releases_the_gil():
    """While one thread is inside Camera.frame, another runs Python. The main thread stamps the
    time at every turn of its loop; stamps in the first half of the frame call exist only if the
    call released the GIL. Checked against calls that hold it (pow(3, 3_000_000), sorting 2M
    floats): 0 stamps there, against 20 000+ for Camera.frame."""
    cam = psns.Camera(width=1224, height=1024)
    cam.frame()  # warm
    done = threading.Event()
    span = []

    def work():
        t0 = time.perf_counter()
        cam.frame(yaw=5)
        span.append((t0, time.perf_counter()))
        done.set()

    stamps = []
    t = threading.Thread(target=work)
    t.start()
    while not done.is_set():
        stamps.append(time.perf_counter())
    t.join()
    t0, t1 = span[0]
    assert t1 - t0 > 0.004, "frame too quick to test"
    inside = sum(t0 + 0.001 < s < (t0 + t1) / 2 for s in stamps)
    assert inside > 10, (inside, t1 - t0)


def test_open_stream_reports_damage_like_verify(psns_bin, tmp_path):
    path = tmp_path / "s.psns"
    stream_file(psns_bin, path)
    data = bytearray(path.read_bytes())
    # flip one payload byte of frame 1 (header 4096 B, then stride-sized frame records)
    stride = (len(data) - 4096) // 3
    data[4096 + stride + 256 + 100] ^= 0xFF
    bad = tmp_path / "bad.psns"
    bad.write_bytes(bytes(data))
    it = psns.open_stream(bad)
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        got = [i for i, _, _ in it]
    assert got == [0, 2]
    msgs = [str(x.message) for x in w if issubclass(x.category, psns.StreamDamageWarning)]
    assert msgs == [f"frame 1 at byte {4096 + stride}: payload CRC mismatch"]
    r = run(psns_bin, "verify", bad, ok=False)
    assert r.returncode == 1
    assert it.report() == r.stdout
    assert not it.intact and it.report_dict()["status"] == "damaged"
    # the clean file: verify's report too
    it = psns.open_stream(path)
    assert len(list(it)) == 3 and it.intact
    assert it.report() == run(psns_bin, "verify", path).stdout
    # damage as an error on request
    with warnings.catch_warnings():
        warnings.simplefilter("error", psns.StreamDamageWarning)
        with pytest.raises(psns.StreamDamageWarning):
            list(psns.open_stream(bad))


def test_open_stream_reports_an_aborted_stream(psns_bin, tmp_path):
    traj = tmp_path / "t.csv"
    traj.write_text("t_s,yaw_deg,pitch_deg,roll_deg\n0,0,0,0\n0.05,NaN,0,0\n")
    path = tmp_path / "a.psns"
    r = run(psns_bin, "stream", "--width", "64", "--height", "48", "--trajectory", traj,
            "--out", path, ok=False)
    assert r.returncode == 2, r.stderr
    why = "trajectory line 3: 'NaN' is not a finite number"
    it = psns.open_stream(path)
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        got = [i for i, _, _ in it]
    assert got == [0]
    msgs = [str(x.message) for x in w if issubclass(x.category, psns.StreamAbortedWarning)]
    assert msgs == [f"stream aborted by its producer: {why}"]
    assert it.aborted == why and it.intact
    assert it.report_dict()["status"] == "aborted"
    v = run(psns_bin, "verify", path, ok=False)
    assert v.returncode == 3 and it.report() == v.stdout
    # an aborted stream is damage to code that stops at damage
    with warnings.catch_warnings():
        warnings.simplefilter("error", psns.StreamDamageWarning)
        with pytest.raises(psns.StreamAbortedWarning):
            list(psns.open_stream(path))


def test_open_stream_reads_a_fifo(psns_bin, tmp_path):
    fifo = tmp_path / "f"
    os.mkfifo(fifo)
    t = threading.Thread(target=stream_file, args=(psns_bin, fifo, ("--pixel-format", "mono12p")))
    t.start()
    frames = list(psns.open_stream(fifo))
    t.join()
    assert [i for i, _, _ in frames] == [0, 1, 2]
    cam = psns.Camera(width=W, height=H, seed=9, frame="enu", **SUN)
    _, y, p, r = POSES[2]
    assert np.array_equal(frames[2][2], cam.frame(yaw=y, pitch=p, roll=r, frame_index=2))


def test_open_stream_errors(tmp_path):
    # a missing input is FileNotFoundError (an OSError, as open() raises), not ValueError
    with pytest.raises(FileNotFoundError, match="missing does not exist"):
        psns.open_stream(tmp_path / "missing")
    with pytest.raises(IsADirectoryError):
        psns.open_stream(tmp_path)
    with pytest.raises(FileNotFoundError, match="nope.toml does not exist"):
        psns.render(config=str(tmp_path / "nope.toml"), width=8, height=8)
    (tmp_path / "x").write_bytes(b"not a stream at all" * 300)
    with pytest.raises(ValueError):
        psns.open_stream(tmp_path / "x")


def test_camera_yaw_is_the_yaw_heading_reports():
    # defaults on both sides: the Camera's yaw and heading's yaw are the same ENU compass heading
    # (an array has no scene.json beside it: heading is told the default sun)
    cam = psns.Camera(seed=3)
    for yaw in (0.0, 30.0, 251.0):
        h = psns.heading(cam.frame(yaw=yaw), sun_zenith=50, sun_azimuth=200)
        gap = (h["yaw_deg"] - yaw) % 360.0
        assert min(gap, 360.0 - gap) < 0.5, (yaw, h)
        assert h["confidence"] > 0.5, (yaw, h)
        solar = psns.heading(cam.frame(yaw=yaw), sun_zenith=50, sun_azimuth=200, frame="solar")
        gap = (solar["yaw_deg"] - (yaw - 200.0)) % 360.0
        assert min(gap, 360.0 - gap) < 0.5, (yaw, solar)
    # no sun given: refused, naming the options that give one
    with pytest.raises(ValueError, match="no sun position"):
        psns.heading(cam.frame(yaw=0.0))
