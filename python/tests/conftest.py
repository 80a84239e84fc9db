"""Shared helpers: the psns binary the Python results are compared with, and a PNG reader (the
tests need nothing beyond numpy and the standard library)."""

import os
import re
import struct
import subprocess
import zlib
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def psns_bin() -> str:
    """The CLI of the same checkout (PSNS_BIN, else target/release/psns). Missing is a failure,
    not a skip: these tests exist to compare the two front-ends."""
    p = os.environ.get("PSNS_BIN") or str(ROOT / "target" / "release" / "psns")
    if not os.access(p, os.X_OK):
        pytest.fail(f"psns binary not found at {p}: run `cargo build --release` or set PSNS_BIN")
    return p


def run(bin_: str, *args: str, ok: bool = True, **kw) -> subprocess.CompletedProcess:
    r = subprocess.run([bin_, *map(str, args)], capture_output=True, text=True, **kw)
    if ok and r.returncode != 0:
        raise AssertionError(f"psns {' '.join(map(str, args))} failed ({r.returncode}): {r.stderr}")
    return r


def cli_message(stderr: str) -> str:
    """The message line the CLI printed, without its "error: " or "psns: " prefix, naming
    options as Python names them: '--sun-zenith <DEG>' is sun_zenith=."""
    line = stderr.strip().splitlines()[0]
    for p in ("psns: ", "error: "):
        if line.startswith(p):
            line = line[len(p):]
    return re.sub(r"'--([a-z0-9-]+)[^']*'", lambda m: m.group(1).replace("-", "_") + "=", line)


def read_png_gray(path) -> np.ndarray:
    """Greyscale 8/16-bit non-interlaced PNG (what psns writes) as uint8/uint16."""
    data = Path(path).read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, idat, w = 8, b"", None
    while pos < len(data):
        (n,) = struct.unpack(">I", data[pos : pos + 4])
        kind = data[pos + 4 : pos + 8]
        body = data[pos + 8 : pos + 8 + n]
        if kind == b"IHDR":
            w, h, depth, color, _, _, interlace = struct.unpack(">IIBBBBB", body)
            assert color == 0 and interlace == 0 and depth in (8, 16)
        elif kind == b"IDAT":
            idat += body
        pos += 12 + n
    bpp = depth // 8
    stride = w * bpp
    raw = zlib.decompress(idat)
    out = np.zeros((h, stride), np.uint8)
    prev = np.zeros(stride, np.int32)
    for y in range(h):
        f = raw[y * (stride + 1)]
        line = np.frombuffer(raw, np.uint8, stride, y * (stride + 1) + 1).astype(np.int32)
        cur = np.zeros(stride, np.int32)
        for x in range(stride):
            a = cur[x - bpp] if x >= bpp else 0
            b = prev[x]
            c = prev[x - bpp] if x >= bpp else 0
            if f == 0:
                p = 0
            elif f == 1:
                p = a
            elif f == 2:
                p = b
            elif f == 3:
                p = (a + b) // 2
            else:
                pa, pb, pc = abs(b - c), abs(a - c), abs(a + b - 2 * c)
                p = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
            cur[x] = (line[x] + p) & 0xFF
        out[y] = cur
        prev = cur
    if depth == 8:
        return out
    return out.reshape(h, w, 2).astype(np.uint16) @ np.array([256, 1], np.uint16)
