"""psns: the polarized-skylight + IMX250MZR camera emulator, from numpy.

Every function runs the Rust library in-process (no subprocess, no files) and releases the GIL
while it works. Keyword arguments are the ``psns`` command line's long options with underscores
(``sun_zenith=50`` is ``--sun-zenith 50``); they are parsed by the CLI's own option code, so a
bad value raises ``ValueError`` with the message the CLI prints. Flags take ``True``; lists
(``quaternion=(1, 0, 0, 0)``, ``off=["prnu", "dsnu"]``) are written as the CLI's comma lists;
``sensor_set={"prnu": 0.01}`` is ``--sensor-set prnu=0.01``.

Arrays: results are numpy arrays that take over the Rust buffer (no copy). Inputs (raw mosaics)
are read once into the library; C-contiguous ``uint16`` is copied with one ``memcpy``.

Axes: images are ``rows x columns`` (``height x width``); angles are in degrees; AoLP/AOP are
measured from the image's +x axis (columns) toward +y (rows, down), in [0, 180).

See docs/python.md for examples.
"""

from __future__ import annotations

import os
from typing import Any, Dict, Iterator, Optional, Tuple

import numpy as np

from . import _psns

__version__: str = _psns.__version__

__all__ = [
    "render",
    "render_raw",
    "Camera",
    "demosaic",
    "open_stream",
    "StreamDamageWarning",
    "StreamAbortedWarning",
    "heading",
    "sky",
    "dataset",
]


class StreamDamageWarning(UserWarning):
    """A damaged, truncated or dropped part of a frame stream (see :func:`open_stream`)."""


class StreamAbortedWarning(StreamDamageWarning):
    """A frame stream whose producer stopped because of a failure (bad input, an I/O error, a
    signal) and marked it aborted: its frames are intact, but it is not the whole run."""


def render(**scene: Any) -> Dict[str, np.ndarray]:
    """Ideal images of a scene, as ``psns render`` computes them.

    Keyword arguments: the scene options of ``psns render`` (``sun_zenith``, ``sun_azimuth`` or
    ``time``/``lat``/``lon``, ``turbidity``, ``wavelength``, ``albedo``, ``model``,
    ``dop_model``, ``yaw``/``pitch``/``roll``/``frame`` or ``quaternion``, ``width``, ``height``,
    ``focal_length``, ``pixel_pitch``, ``principal_point``, ``projection`` (rectilinear,
    equidistant, equisolid, stereographic, orthographic), ``lens`` (pinhole, ideal), ``config``
    (a scene file), ...).

    Returns ``{"li", "dop", "aop"}``: float32 arrays ``height x width``, identical to the CLI's
    ``li.npy``, ``dop.npy`` and ``aop.npy`` (AOP in degrees).
    """
    return _psns.render(**scene)


def render_raw(**scene_and_sensor: Any) -> Dict[str, Any]:
    """The IMX250MZR raw frame of a scene and its ground truth, as ``psns render --raw``.

    Keyword arguments: the scene options of :func:`render` plus the sensor options of
    ``psns render --raw`` (``preset``, ``seed``, ``frame_index``, ``exposure_us`` or
    ``auto_exposure=True``, ``gain_db``, ``bit_depth``, ``black_level``, ``sun_disc``,
    ``clouds=True``, ``sky_grid``, ``exact=True``, ``off=[...]``, ``sensor_set={...}``, ...).

    Returns ``raw``: the ADC codes (``uint16``, or ``uint8`` for ``bit_depth=8``), identical to
    the CLI's ``raw.png`` for the same options and seed; ``truth_s0``, ``truth_s1``,
    ``truth_s2``, ``truth_dolp``, ``truth_aolp`` (float32, DN above the black level; AoLP in
    degrees), identical to the CLI's ``truth_*.npy``; and ``meta`` (exposure, gain, bit depth,
    black level, DN per electron, saturated pixels per mosaic position).
    """
    return _psns.render_raw(**scene_and_sensor)


class Camera:
    """A camera for fast loops: fixed patterns and caches are built once, then each
    :meth:`frame` renders one raw frame in-process (the fast path of ``psns stream``).

    ``Camera(preset="camera", seed=1, width=2448, height=2048, **sensor)`` takes every option of
    :func:`render_raw`. The attitude frame (``frame="enu"``, the default: yaw is the compass heading
    that :func:`heading` reports; or ``"solar"``: yaw from the sun's azimuth), the sun (``sun_zenith`` and
    ``sun_azimuth`` or ``time``/``lat``/``lon``) and the attitude given here are the defaults of
    :meth:`frame`.
    """

    def __init__(self, **scene_and_sensor: Any) -> None:
        self._cam = _psns.Camera(**scene_and_sensor)

    @property
    def width(self) -> int:
        """Columns."""
        return self._cam.width

    @property
    def height(self) -> int:
        """Rows."""
        return self._cam.height

    @property
    def bit_depth(self) -> int:
        """ADC bits of the codes (8, 10 or 12)."""
        return self._cam.bit_depth

    @property
    def config(self) -> str:
        """The scene and sensor configuration as JSON (what ``scene.json`` records)."""
        return self._cam.config

    def frame(
        self,
        yaw: Optional[float] = None,
        pitch: Optional[float] = None,
        roll: Optional[float] = None,
        sun_zenith: Optional[float] = None,
        sun_azimuth: Optional[float] = None,
        frame_index: Optional[int] = None,
        meta: bool = False,
    ) -> Any:
        """One raw frame (ADC codes, ``height x width``, ``uint16``; ``uint8`` at 8 bits).

        Attitude in degrees in the camera's attitude frame; an angle left out keeps the
        constructor's value. The sun likewise. ``frame_index`` selects the temporal noise
        (default: one more than the last frame, starting at the constructor's
        ``frame_index``); the same camera, pose, sun and index give the same frame, bit for bit,
        whatever the number of threads. The array is new for each call (it owns the Rust
        buffer: no copy, no reuse). With ``meta=True`` returns ``(frame, dict)`` with the
        exposure, saturated pixels and the sun.
        """
        return self._cam.frame(
            yaw=yaw,
            pitch=pitch,
            roll=roll,
            sun_zenith=sun_zenith,
            sun_azimuth=sun_azimuth,
            frame_index=frame_index,
            meta=meta,
        )


def demosaic(
    raw: np.ndarray, method: str = "bilinear", black_level: float = 0.0, **opts: Any
) -> Dict[str, np.ndarray]:
    """S0, S1, S2, DoLP and AoLP of a raw mosaic, as ``psns demosaic``.

    ``raw``: 2-D ``uint16`` or ``uint8`` codes. ``method``: superpixel, bilinear, bicubic,
    ppid, newton, eari. ``black_level`` (DN) is subtracted first (the CLI takes it from a
    stream's metadata). Options: ``layout="90,45/135,0"`` (the IMX250MZR's), ``dolp_debias``
    (noise sigma of S1/S2 in DN: also returns ``dolp_debiased``).

    Returns float32 arrays ``s0``, ``s1``, ``s2``, ``dolp``, ``aolp`` (degrees), identical to the
    CLI's ``.npy`` files for the same input.
    """
    return _psns.demosaic(raw, method=method, black_level=black_level, **opts)


def heading(raw: np.ndarray, **sun_and_tilt: Any) -> Dict[str, float]:
    """The camera's yaw (ENU compass heading) from one raw mosaic, as ``psns heading IMAGE``.

    Give the sun (``sun_zenith``/``sun_altitude`` and ``sun_azimuth``, or ``time``, ``lat``,
    ``lon``, or ``config``: a scene file such as the ``scene.json`` of ``psns render``; without
    one it raises ValueError, as an array has no scene file beside it), the camera's intrinsics if not the default camera (``width``, ``height``,
    ``focal_length``, ``pixel_pitch``) and its known tilt (``pitch``, ``roll``); also
    ``method`` (model-fit, eigen, hough), ``demosaic``, ``bits``, and ``preset`` (the sensor
    preset the frame was made with: its lens and edge falloff) or ``vignetting_cos_power`` (the
    falloff's cos^N law, for the 180 degree decision near the horizon), ``frame`` ("enu", the
    default: yaw from north; "solar": from the sun's azimuth), ``mask`` ("auto", the default:
    the sky found from the frame; "none"; or a PNG/TIFF of the frame's size, nonzero = sky).
    The estimate uses nothing else. Returns ``yaw_deg`` (NaN when too few pixels are usable or
    the sun is within 0.27 degrees of the zenith), ``confidence`` (0..1), ``pixels``,
    ``saturated_pixels``, ``residual_deg`` (RMS AoLP residual against the estimator's sky model
    at that yaw, DoLP^2 weighted; NaN without a yaw; large when the tilt, sun or lens given do
    not fit the sky) and ``sky_fraction`` (the share of the image used as sky; 0 without a yaw).
    """
    return _psns.heading(raw, **sun_and_tilt)


def sky(zenith: Any, azimuth: Any, **sky: Any) -> Dict[str, np.ndarray]:
    """Sky values for directions, as ``psns sky``, vectorised over numpy arrays.

    ``zenith`` (0..180) and ``azimuth`` (compass, from north, clockwise) in degrees are
    broadcast together. Keyword arguments: the scene options of :func:`render` (sun, sky).
    Returns float64 arrays of the broadcast shape: ``gamma_deg`` (angle from the sun),
    ``radiance`` (W m^-2 sr^-1 nm^-1), ``dop``, ``aop_meridian_deg``, ``aop_north_deg``; zero at
    and below the horizon.
    """
    return _psns.sky(zenith, azimuth, **sky)


def open_stream(path: "os.PathLike[str] | str") -> "_psns.StreamIter":
    """Iterate over a psns frame stream (file, growing file, FIFO, or ``"-"`` for stdin).

    Yields ``(frame_index, metadata, frame)`` for every intact frame: ``metadata`` is the frame
    header as a dict (exposure, gain, black level, sun, attitude quaternion, saturated pixels,
    ...), ``frame`` the unpacked codes (``uint16``, ``height x width``, LSB-aligned unless the
    stream says ``msb_aligned``). Each ``frame`` is a new array that owns its buffer: the reader
    keeps no reference and never overwrites it.

    Damage is reported as ``psns verify`` reports it: every damaged or truncated record raises a
    :class:`StreamDamageWarning` (``"frame 7 at byte 123: payload CRC mismatch"``) and is skipped;
    reading resynchronises on the next intact frame. ``it.report()`` is the text ``psns verify``
    prints for what was read so far, ``it.report_dict()`` its ``--json`` form, ``it.intact``
    whether nothing was damaged, dropped or skipped, ``it.header`` the file header. Use
    ``warnings.simplefilter("error", psns.StreamDamageWarning)`` to stop at the first damage.

    A stream its producer marked aborted (bad input, an I/O error or a signal stopped it) raises
    a :class:`StreamAbortedWarning` (a kind of ``StreamDamageWarning``) with the reason when its
    end is read; ``it.aborted`` is then the reason (else ``None``) and ``it.report_dict()``'s
    ``status`` is ``"aborted"``.
    """
    return _psns.open_stream(os.fspath(path))


from . import dataset  # noqa: E402  (needs the names above)
