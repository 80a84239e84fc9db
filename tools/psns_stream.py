#!/usr/bin/env python3
"""Reader for psns raw frame streams, format v1 (docs/stream-format.md). Needs numpy only.

Library use:
    import psns_stream as ps
    hdr, frames = ps.open_memmap("run.psns")       # regular file: zero-copy structured array
    img = ps.unpack(frames[0]["payload"], hdr)       # (height, width) uint16 values
    for meta, img, crc_ok in ps.iter_frames(open("run.psns", "rb")):   # files, FIFOs, stdin
        ...
Command line:
    psns_stream.py info FILE          header and per-frame metadata as JSON
    psns_stream.py dump FILE|-        canonical text lines (used by the test suite)
    psns_stream.py frame FILE N OUT   write frame N's values as raw uint16 little-endian
"""
import json
import struct
import sys
import zlib

import numpy as np

FILE_MAGIC = b"\x89PSNSRAW"
FRAME_MAGIC = b"\x89PSNSFRM"
PFNC = {0x01080001: "Mono8", 0x010C0047: "Mono12p", 0x010C0006: "Mono12Packed", 0x01100007: "Mono16"}
CAMERA = ["pixel_pitch_um", "focal_length_mm", "f_number", "wavelength_nm", "bandwidth_nm",
          "full_well_e", "k0_dn_per_e", "read_noise_e", "principal_col", "principal_row"]

# frame header fields (offset, dtype); payload follows at 256
FRAME_FIELDS = [
    ("magic", "S8", 0), ("index", "<u8", 8), ("flags", "<u4", 16), ("payload_crc", "<u4", 20),
    ("exposure_start_ns", "<i8", 24), ("exposure_end_ns", "<i8", 32), ("host_time_ns", "<i8", 40),
    ("exposure_us", "<f8", 48), ("gain_db", "<f8", 56), ("black_level", "<f8", 64),
    ("temperature_c", "<f8", 72), ("sun_azimuth_deg", "<f8", 80), ("sun_elevation_deg", "<f8", 88),
    ("sun_camera", ("<f8", (3,)), 96), ("attitude_wxyz", ("<f8", (4,)), 120),
    ("lat_deg", "<f8", 152), ("lon_deg", "<f8", 160), ("height_m", "<f8", 168),
    ("saturated", ("<u4", (4,)), 176), ("turbidity", "<f4", 192), ("albedo", "<f4", 196),
    ("header_crc", "<u4", 252),
]
F64_ORDER = ["exposure_us", "gain_db", "black_level", "temperature_c", "sun_azimuth_deg",
             "sun_elevation_deg", "sun_camera", "attitude_wxyz", "lat_deg", "lon_deg", "height_m"]


class StreamError(Exception):
    pass


def parse_header(b):
    """Parses and checks the 4096-byte file header; returns a dict."""
    if len(b) < 4096 or b[:8] != FILE_MAGIC:
        raise StreamError("not a psns stream")
    if zlib.crc32(b[:4092]) != struct.unpack_from("<I", b, 4092)[0]:
        raise StreamError("file header CRC mismatch")
    major, minor, fhs, frs, w, h, code, bits, align = struct.unpack_from("<HHIIIIIHH", b, 8)
    if major != 1 or fhs != 4096 or frs != 256:
        raise StreamError("unsupported version or header sizes")
    if code not in PFNC:
        raise StreamError("unsupported PFNC code %#x" % code)
    angles = struct.unpack_from("<4h", b, 36)
    sense = struct.unpack_from("<h", b, 44)[0]
    payload, stride, count, seed = struct.unpack_from("<4Q", b, 48)
    cam = struct.unpack_from("<10d", b, 80)
    jo, jl = struct.unpack_from("<II", b, 224)
    hdr = dict(version=(major, minor), width=w, height=h, pfnc=code, pixel_format=PFNC[code],
               bits_valid=bits, msb_aligned=bool(align), angles_deg=list(angles), angle_sense=sense,
               payload_size=payload, stride=stride, frame_count=count, seed=seed,
               camera=dict(zip(CAMERA, cam)),
               producer=b[160:192].split(b"\0")[0].decode(), preset=b[192:224].split(b"\0")[0].decode(),
               json=b[jo:jo + jl].decode() if jl else "")
    n = w * h
    want = {"Mono8": n, "Mono16": 2 * n}.get(hdr["pixel_format"], (3 * n + 1) // 2)
    if payload != want or stride != -(-(256 + payload) // 4096) * 4096:
        raise StreamError("payload size / stride inconsistent")
    return hdr


def frame_dtype(hdr):
    """One structured dtype for a whole record (itemsize = stride)."""
    names, formats, offsets = [], [], []
    for name, fmt, off in FRAME_FIELDS:
        names.append(name); formats.append(fmt); offsets.append(off)
    if hdr["pixel_format"] == "Mono16":
        pay = ("<u2", (hdr["height"], hdr["width"]))
    elif hdr["pixel_format"] == "Mono8":
        pay = ("u1", (hdr["height"], hdr["width"]))
    else:
        pay = ("u1", (hdr["payload_size"],))
    names.append("payload"); formats.append(pay); offsets.append(256)
    return np.dtype(dict(names=names, formats=formats, offsets=offsets, itemsize=hdr["stride"]))


def open_memmap(path):
    """(header, frames) for a regular file; frames[i]['payload'] without copying.
    Only whole records are mapped; check CRCs with check_frame()."""
    with open(path, "rb") as f:
        hdr = parse_header(f.read(4096))
        f.seek(0, 2)
        size = f.tell()
    n = (size - 4096) // hdr["stride"]
    return hdr, np.memmap(path, frame_dtype(hdr), mode="r", offset=4096, shape=(n,))


def unpack(payload, hdr):
    """Payload (any array/bytes) -> (height, width) uint16 values with bits_valid bits."""
    h, w, fmt = hdr["height"], hdr["width"], hdr["pixel_format"]
    b = np.frombuffer(np.ascontiguousarray(payload).tobytes(), np.uint8)
    n = w * h
    if fmt == "Mono8":
        v = b.astype(np.uint16)
    elif fmt == "Mono16":
        v = b.view("<u2").astype(np.uint16)
        if hdr["msb_aligned"]:
            v = v >> (16 - hdr["bits_valid"])
    else:
        pad = np.zeros(-len(b) % 3, np.uint8)
        g = np.concatenate([b, pad]).reshape(-1, 3).astype(np.uint16)
        if fmt == "Mono12p":
            p0 = g[:, 0] | ((g[:, 1] & 0x0F) << 8)
        else:
            p0 = (g[:, 0] << 4) | (g[:, 1] & 0x0F)
        p1 = (g[:, 1] >> 4) | (g[:, 2] << 4)
        v = np.stack([p0, p1], axis=1).reshape(-1)[:n]
    return v.reshape(h, w)


def _meta(rec):
    m = {}
    for name, _, _ in FRAME_FIELDS:
        if name in ("magic", "header_crc"):
            continue
        x = rec[name]
        m[name] = x.tolist() if hasattr(x, "tolist") else x
    return m


def check_frame(hdr, rec):
    """(header_ok, payload_ok) of one memmapped record."""
    raw = rec.tobytes()
    hok = raw[:8] == FRAME_MAGIC and zlib.crc32(raw[:252]) == struct.unpack_from("<I", raw, 252)[0]
    pok = zlib.crc32(raw[256:256 + hdr["payload_size"]]) == struct.unpack_from("<I", raw, 20)[0]
    return hok, pok


def iter_frames(f, report=None):
    """Yields (meta, values, payload_crc_ok) from a binary file object (file, FIFO, stdin).
    Damage is passed to report(str) (default: stderr) and skipped by scanning for the magic."""
    report = report or (lambda s: print(s, file=sys.stderr))
    buf = bytearray()
    eof = False

    def fill(n):
        nonlocal eof
        while len(buf) < n and not eof:
            c = f.read(max(n - len(buf), 1 << 16))
            if not c:
                eof = True
            else:
                buf.extend(c)

    fill(4096)
    hdr = parse_header(bytes(buf[:4096]))
    del buf[:4096]
    dt = None
    while True:
        fill(8)
        if not buf:
            return
        if buf[:8] == FILE_MAGIC:
            fill(4096)
            try:
                hdr = parse_header(bytes(buf[:4096]))
                del buf[:4096]
                report("producer restart")
                continue
            except StreamError:
                pass
        elif buf[:8] == FRAME_MAGIC:
            fill(256)
            hb = bytes(buf[:256])
            if len(hb) == 256 and zlib.crc32(hb[:252]) == struct.unpack_from("<I", hb, 252)[0]:
                stride = hdr["stride"]
                fill(stride)
                if len(buf) < stride:
                    report("truncated frame %d" % struct.unpack_from("<Q", hb, 8)[0])
                    return
                rec = np.frombuffer(bytes(buf[:stride]), frame_dtype(hdr))[0]
                del buf[:stride]
                ok = check_frame(hdr, rec)[1]
                if not ok:
                    report("frame %d: payload CRC mismatch" % rec["index"])
                yield _meta(rec), unpack(rec["payload"], hdr), ok
                continue
        # damage: skip to the next magic
        i = buf.find(b"\x89PSNS", 1)
        while i < 0 and not eof:
            keep = buf[-4:]
            del buf[:]
            buf.extend(keep)
            fill(1 << 16)
            i = buf.find(b"\x89PSNS", 1)
        report("damaged data skipped")
        if i < 0:
            return
        del buf[:i]


def _hex64(x):
    return "%016x" % struct.unpack("<Q", struct.pack("<d", x))[0]


def canonical(meta, values, ok):
    f64 = []
    for k in F64_ORDER:
        v = meta[k]
        f64 += v if isinstance(v, list) else [v]
    f32 = ["%08x" % struct.unpack("<I", struct.pack("<f", meta[k]))[0] for k in ("turbidity", "albedo")]
    v = np.ascontiguousarray(values, dtype="<u2")
    return "frame %d %d %d %d %d %d %s %s %s %d %08x" % (
        meta["index"], meta["flags"], int(ok), meta["exposure_start_ns"], meta["exposure_end_ns"],
        meta["host_time_ns"], ",".join(_hex64(x) for x in f64),
        ",".join(str(s) for s in meta["saturated"]), ",".join(f32), int(v.sum(dtype=np.uint64)),
        zlib.crc32(v.tobytes()))


def canonical_header(h):
    return "header %d %d %08x %d %d %d %d %d %d %s" % (
        h["width"], h["height"], h["pfnc"], h["bits_valid"], int(h["msb_aligned"]), h["seed"],
        h["frame_count"], h["payload_size"], h["stride"], ",".join(str(a) for a in h["angles_deg"]))


def main(argv):
    if len(argv) < 3 or argv[1] not in ("info", "dump", "frame"):
        print(__doc__, file=sys.stderr)
        return 2
    cmd, path = argv[1], argv[2]
    f = sys.stdin.buffer if path == "-" else open(path, "rb")
    if cmd == "dump":
        head = f.read(4096)
        print(canonical_header(parse_header(head)))
        for meta, values, ok in iter_frames(_Prefixed(head, f)):
            print(canonical(meta, values, ok))
        return 0
    if cmd == "info":
        hdr, frames = open_memmap(path)
        out = dict(header=hdr, frames=[])
        for rec in frames:
            hok, pok = check_frame(hdr, rec)
            m = _meta(rec) if hok else {}
            m.update(header_crc_ok=hok, payload_crc_ok=pok)
            out["frames"].append(m)
        print(json.dumps(out, indent=1))
        return 0
    n = int(argv[3])
    for meta, values, ok in iter_frames(f):
        if meta["index"] == n and ok:
            np.ascontiguousarray(values, dtype="<u2").tofile(argv[4])
            return 0
    print("frame %d not found or damaged" % n, file=sys.stderr)
    return 1


class _Prefixed:
    """A file object with bytes already read put back in front."""

    def __init__(self, head, f):
        self.head, self.f = bytes(head), f

    def read(self, n):
        if self.head:
            out, self.head = self.head[:n], self.head[n:]
            return out
        return self.f.read(n)


if __name__ == "__main__":
    sys.exit(main(sys.argv))
