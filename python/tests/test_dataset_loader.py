"""Shards on a real engine (dask.distributed), the dataset from Python, the data loader."""

import hashlib
import time
from pathlib import Path

import numpy as np
import pytest

import psns
import psns.dataset
import psns.loader
from conftest import cli_message, run

CONFIG = "seed = 7\nwidth = 64\nheight = 48\n[splits]\nNFPI = 3\nGNIICPI = 3\nTGNIIPI = 3\n"


def tree(d: Path):
    return {
        str(p.relative_to(d)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(d.rglob("*"))
        if p.is_file()
    }


def test_three_dask_shards_equal_one_build(psns_bin, tmp_path):
    import distributed  # installed by .ci/run (tools/test): missing is a failure, not a skip
    cfg = tmp_path / "d.toml"
    cfg.write_text(CONFIG)
    whole = tmp_path / "whole"
    run(psns_bin, "dataset", "build", "--config", cfg, "--out", whole)
    sharded = tmp_path / "sharded"
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1", dashboard_address=None
    ) as cluster, distributed.Client(cluster) as client:
        built = psns.dataset.build_on_dask(client, cfg, sharded, shards=3)
    assert sorted(built) == [1, 2, 3]
    a, b = tree(whole), tree(sharded)
    assert len(a) > 9 and "manifest.csv" in a
    assert {k for k in b if k not in a} <= {k for k in b if "shard" in k}, "unexpected files"
    for k, h in a.items():
        assert b.get(k) == h, k
    r = run(psns_bin, "dataset", "verify", sharded)
    assert r.returncode == 0


def test_dataset_build_in_process_and_errors(psns_bin, tmp_path):
    cfg = tmp_path / "d.toml"
    cfg.write_text(CONFIG)
    psns.dataset.build(cfg, tmp_path / "a", shard=(2, 3))
    psns.dataset.build(cfg, tmp_path / "a", shard=(1, 3))
    psns.dataset.build(cfg, tmp_path / "a", shard=(3, 3))
    run(psns_bin, "dataset", "build", "--config", cfg, "--out", tmp_path / "b")
    assert tree(tmp_path / "a")["manifest.csv"] == tree(tmp_path / "b")["manifest.csv"]
    r = run(psns_bin, "dataset", "build", "--config", cfg, "--out", tmp_path / "c", "--shard", "4/3", ok=False)
    assert r.returncode == 2
    with pytest.raises(ValueError) as e:
        psns.dataset.build(cfg, tmp_path / "c", shard=(4, 3))
    assert str(e.value) == cli_message(r.stderr)
    assert not (tmp_path / "c").exists()


def test_dataset_build_dry_run_prints_the_plan_and_creates_nothing(capfd, tmp_path):
    # the default description: 138,000 full-size images, planned and not started
    psns.dataset.build(None, tmp_path / "psns", dry_run=True, jobs=2)
    err = capfd.readouterr().err
    assert "plan: 138000 samples of 2448 x 2048" in err and "GB" in err and " h " in err, err
    assert not (tmp_path / "psns").exists()


def test_frame_dataset_is_a_function_of_seed_and_index():
    ds = psns.loader.FrameDataset(samples=4, seed=3, width=64, height=48)
    a = list(ds)
    b = list(psns.loader.FrameDataset(samples=4, seed=3, width=64, height=48))
    assert len(a) == 4
    for (fa, la), (fb, lb) in zip(a, b):
        assert fa.shape == (1, 48, 64) and fa.dtype == np.float32
        assert 0.0 <= fa.min() and fa.max() <= 1.0 and fa.max() > 0.0
        assert la == lb and np.array_equal(fa, fb)
    # sample i alone gives the same as in the sequence
    f2, l2 = ds.sample(2)
    assert l2 == a[2][1] and np.array_equal(f2, a[2][0])
    assert a[0][1] != a[1][1]
    # the label's pose is the frame's pose: the heading consumer recovers the yaw
    ds = psns.loader.FrameDataset(samples=1, seed=5, width=612, height=512, normalize=False, max_tilt=0.0)
    frame, lab = next(iter(ds))
    h = psns.heading(frame[0], width=612, height=512, sun_zenith=lab["sun_zenith_deg"],
                     sun_azimuth=lab["sun_azimuth_deg"])
    err = (h["yaw_deg"] - lab["yaw_deg"] + 180.0) % 360.0 - 180.0
    assert abs(err) < 0.5, (h, lab)
