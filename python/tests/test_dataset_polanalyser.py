"""The dataset's 8-bit raw mosaics are "readable by polanalyser": polanalyser, given a
file of a built dataset as OpenCV reads it, demosaics it as psns does."""

import numpy as np

import psns
import psns.dataset


def test_dataset_png_is_read_by_polanalyser(tmp_path):
    import cv2
    import polanalyser as pa

    cfg = tmp_path / "d.toml"
    # a clear, well polarized sky (the default distributions include hazy red skies with DOP ~0.01)
    cfg.write_text(
        "seed = 3\nwidth = 256\nheight = 192\nturbidity = 3\nwavelength_nm = 450\nsun_altitude_deg = 30\n"
        "[splits]\nNFPI = 1\nGNIIPI = 1\n"
    )
    psns.dataset.build(cfg, tmp_path / "ds")
    files = sorted((tmp_path / "ds").glob("*/*.png"))
    assert len(files) == 2
    for f in files:
        raw = cv2.imread(str(f), cv2.IMREAD_UNCHANGED)
        assert raw.dtype == np.uint8 and raw.shape == (192, 256)
        i0, i45, i90, i135 = pa.demosaicing(raw, pa.COLOR_PolarMono)
        stokes = pa.calcStokes([i0, i45, i90, i135], np.deg2rad([0, 45, 90, 135]))
        theirs = np.rad2deg(pa.cvtStokesToAoLP(stokes)) % 180.0
        ours = psns.demosaic(raw)
        inner = (slice(4, -4), slice(4, -4))
        sky = ours["dolp"][inner] > 0.05
        d = np.abs((ours["aolp"][inner] - theirs[inner] + 90.0) % 180.0 - 90.0)[sky]
        assert sky.mean() > 0.5 and np.median(d) < 0.5, (f.name, np.median(d))
