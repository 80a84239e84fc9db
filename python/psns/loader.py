"""Freshly emulated frames for training: a PyTorch-style ``IterableDataset``.

``FrameDataset`` draws a pose and a sun position per sample from its seed, renders the raw frame
with :class:`psns.Camera` and yields ``(frame, label)``. It subclasses
``torch.utils.data.IterableDataset`` when PyTorch is installed and is a plain iterable
otherwise, so it works (and is tested) without torch. With a ``DataLoader`` of several workers,
each worker takes every ``num_workers``-th sample, so the samples do not depend on the number of
workers::

    from torch.utils.data import DataLoader
    ds = psns.loader.FrameDataset(samples=10_000, seed=7, width=612, height=512)
    for frames, labels in DataLoader(ds, batch_size=8, num_workers=2):
        ...  # frames: float32 tensor B x 1 x H x W; labels["yaw_deg"]: B

Each sample ``i`` is a pure function of ``(seed, i)``: its pose, sun and sensor noise
(frame index ``i``) come from ``seed`` and ``i`` alone.
"""

from __future__ import annotations

from typing import Any, Dict, Iterator, Optional, Tuple

import numpy as np

from . import Camera

try:  # torch is optional: the dataset is a plain iterable without it
    from torch.utils.data import IterableDataset as _Base
    from torch.utils.data import get_worker_info as _worker_info
except ImportError:  # pragma: no cover - depends on the environment
    _Base = object

    def _worker_info() -> Any:
        return None


class FrameDataset(_Base):  # type: ignore[misc, valid-type]
    """``samples`` raw frames with labels ``yaw_deg``, ``pitch_deg``, ``roll_deg``,
    ``sun_zenith_deg``, ``sun_azimuth_deg``, ``frame_index`` (ENU frame).

    Poses: yaw uniform in [0, 360), pitch and roll uniform in +-``max_tilt`` degrees; sun zenith
    uniform in ``sun_zenith`` (a (low, high) range, degrees), sun azimuth uniform in [0, 360).
    Frames are float32 ``1 x H x W`` scaled to [0, 1] by the ADC's full scale (``normalize``),
    or the raw codes (``normalize=False``). Other keyword arguments go to :class:`psns.Camera`
    (``preset``, ``width``, ``height``, ``bit_depth``, ``turbidity``, ...)."""

    def __init__(
        self,
        samples: int,
        seed: int = 0,
        max_tilt: float = 5.0,
        sun_zenith: Tuple[float, float] = (20.0, 80.0),
        normalize: bool = True,
        **camera: Any,
    ) -> None:
        if samples < 0:
            raise ValueError(f"samples = {samples} is out of range (allowed 0..)")
        self.samples = int(samples)
        self.seed = int(seed)
        self.max_tilt = float(max_tilt)
        self.sun_zenith = (float(sun_zenith[0]), float(sun_zenith[1]))
        self.normalize = normalize
        self.camera_options = dict(camera, frame="enu", seed=self.seed)
        self._camera: Optional[Camera] = None

    def __len__(self) -> int:
        return self.samples

    def label(self, i: int) -> Dict[str, float]:
        """The pose and sun of sample ``i`` (a pure function of the seed and ``i``)."""
        rng = np.random.default_rng([self.seed, i])
        u = rng.random(5)
        lo, hi = self.sun_zenith
        return {
            "yaw_deg": 360.0 * u[0],
            "pitch_deg": self.max_tilt * (2.0 * u[1] - 1.0),
            "roll_deg": self.max_tilt * (2.0 * u[2] - 1.0),
            "sun_zenith_deg": lo + (hi - lo) * u[3],
            "sun_azimuth_deg": 360.0 * u[4],
            "frame_index": i,
        }

    def sample(self, i: int) -> Tuple[np.ndarray, Dict[str, float]]:
        """Sample ``i``: ``(frame, label)``."""
        if self._camera is None:  # built lazily, once per worker process
            self._camera = Camera(**self.camera_options)
        lab = self.label(i)
        codes = self._camera.frame(
            yaw=lab["yaw_deg"],
            pitch=lab["pitch_deg"],
            roll=lab["roll_deg"],
            sun_zenith=lab["sun_zenith_deg"],
            sun_azimuth=lab["sun_azimuth_deg"],
            frame_index=i,
        )
        if self.normalize:
            full = float((1 << self._camera.bit_depth) - 1)
            frame = (codes.astype(np.float32) / full)[None, :, :]
        else:
            frame = codes[None, :, :]
        return frame, lab

    def __iter__(self) -> Iterator[Tuple[np.ndarray, Dict[str, float]]]:
        info = _worker_info()
        start, step = (0, 1) if info is None else (info.id, info.num_workers)
        for i in range(start, self.samples, step):
            yield self.sample(i)
