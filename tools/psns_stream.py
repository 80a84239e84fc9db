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
    psns_stream.py dump FILE|-        canonical text lines, one per event (used by the test suite)
    psns_stream.py mmdump FILE        canonical lines of the whole records via numpy.memmap
    psns_stream.py frame FILE N OUT   write frame N's values as raw uint16 little-endian
    dump and frame take --recover [--width W --height H --pixel-format F]: degraded mode for a
    damaged file header (docs/stream-format.md)
"""
import json
import os
import struct
import sys
import zlib

try:
    import numpy as np
except ImportError:  # a message, not a traceback: the reader's one dependency is missing
    sys.exit("psns_stream.py needs numpy: python3 -m pip install numpy "
             "(or use the project's .venv made by tools/test)")

FILE_MAGIC = b"\x89PSNSRAW"
FRAME_MAGIC = b"\x89PSNSFRM"
END_MAGIC = b"\x89PSNSEND"
END_REASON_MAX = 228
REASON_NOT_RECORDED = "reason not recorded (the header is marked aborted, the end record is missing)"
# the pixel formats, one row each: PFNC code -> (name, bits per pixel); a payload of n pixels
# is ceil(n * bits / 8) bytes
FORMATS = {0x01080001: ("Mono8", 8), 0x010C0047: ("Mono12p", 12), 0x010C0006: ("Mono12Packed", 12),
           0x01100007: ("Mono16", 16)}
PFNC = {code: name for code, (name, _) in FORMATS.items()}
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
    ("class_fractions", ("<f4", (6,)), 200), ("header_crc", "<u4", 252),
]
F64_ORDER = ["exposure_us", "gain_db", "black_level", "temperature_c", "sun_azimuth_deg",
             "sun_elevation_deg", "sun_camera", "attitude_wxyz", "lat_deg", "lon_deg", "height_m"]


class StreamError(Exception):
    pass


MAX_PAYLOAD = 1 << 30
CONTAINER_BITS = {name: bits for name, bits in FORMATS.values()}


def payload_size(fmt, w, h):
    """Payload bytes of one w x h frame (Python ints: no overflow)."""
    return -(-w * h * CONTAINER_BITS[fmt] // 8)


def pixel_counts(fmt, p):
    """The pixel counts whose payload in format fmt is p bytes."""
    bits = CONTAINER_BITS[fmt]
    n = 8 * p // bits
    return [k for k in (n, n + 1) if -(-k * bits // 8) == p]


def stride_for(p):
    return -(-(256 + p) // 4096) * 4096


def _cstr(f, what):
    s = f.split(b"\0")[0]
    if any(f[len(s):]):
        raise StreamError("%s field is not NUL-padded" % what)
    try:
        return s.decode()
    except UnicodeDecodeError:
        raise StreamError("%s field is not UTF-8" % what)


def parse_header(b):
    """Parses and checks the 4096-byte file header (the checks of Rust FileHeader::decode);
    returns a dict or raises StreamError."""
    b = bytes(b)
    if len(b) < 4096 or b[:8] != FILE_MAGIC:
        raise StreamError("not a psns stream")
    if zlib.crc32(b[:4092]) != struct.unpack_from("<I", b, 4092)[0]:
        raise StreamError("file header CRC mismatch")
    major, minor, fhs, frs, w, h, code, bits, align = struct.unpack_from("<HHIIIIIHH", b, 8)
    if major != 1 or fhs != 4096 or frs != 256:
        raise StreamError("unsupported version or header sizes")
    if code not in PFNC:
        raise StreamError("unsupported PFNC code %#x" % code)
    fmt = PFNC[code]
    if align > 1:
        raise StreamError("alignment code %d (0 or 1)" % align)
    angles = struct.unpack_from("<4h", b, 36)
    if sorted(angles) != [0, 45, 90, 135]:
        raise StreamError("polarizer angles %s are not a permutation of 0, 45, 90, 135" % (angles,))
    sense, end = struct.unpack_from("<hH", b, 44)
    if end > 1:
        raise StreamError("end status %d (0 or 1)" % end)
    payload, stride, count, seed = struct.unpack_from("<4Q", b, 48)
    cam = struct.unpack_from("<10d", b, 80)
    jo, jl = struct.unpack_from("<II", b, 224)
    if (jo, jl) != (0, 0) and (jo < 232 or jo + jl > 4092):
        raise StreamError("JSON at %d + %d outside the header" % (jo, jl))
    try:
        js = b[jo:jo + jl].decode() if (jo, jl) != (0, 0) else ""
    except UnicodeDecodeError:
        raise StreamError("header JSON is not UTF-8")
    producer, preset = _cstr(b[160:192], "producer"), _cstr(b[192:224], "preset")
    if not (1 <= w <= 65535 and 1 <= h <= 65535):
        raise StreamError("frame size %d x %d out of range (1..65535 each)" % (w, h))
    want = payload_size(fmt, w, h)
    if want > MAX_PAYLOAD:
        raise StreamError("payload of %d bytes exceeds %d" % (want, MAX_PAYLOAD))
    if not (bits == 8 if fmt == "Mono8" else 1 <= bits <= CONTAINER_BITS[fmt]):
        raise StreamError("%s with %d valid bits" % (fmt, bits))
    if align and fmt != "Mono16":
        raise StreamError("MSB alignment exists only for Mono16")
    if sense not in (1, -1):
        raise StreamError("angle sense %d (must be +1 or -1)" % sense)
    if "\0" in js:
        raise StreamError("header JSON contains NUL")
    if payload != want or stride != stride_for(want):
        raise StreamError("payload size / stride inconsistent")
    hdr = dict(version=(major, minor), width=w, height=h, pfnc=code, pixel_format=fmt,
               bits_valid=bits, msb_aligned=bool(align), angles_deg=list(angles), angle_sense=sense,
               payload_size=payload, stride=stride, frame_count=count, aborted=bool(end),
               seed=seed, camera=dict(zip(CAMERA, cam)), producer=producer, preset=preset, json=js)
    return hdr


def parse_end(b):
    """(frames, reason) of a 256-byte end record (written after the last frame when the producer
    stopped because of a failure), or None if `b` is not a valid one."""
    b = bytes(b)
    if len(b) < 256 or b[:8] != END_MAGIC or zlib.crc32(b[:252]) != struct.unpack_from("<I", b, 252)[0]:
        return None
    frames, status, n = struct.unpack_from("<QII", b, 8)
    if status != 1 or n > END_REASON_MAX:
        return None
    try:
        return frames, b[24:24 + n].decode()
    except UnicodeDecodeError:
        return None


def _end_after(path, hdr, n):
    """(offset, frames, reason) of a valid end record right after the n whole records, or None."""
    off = 4096 + n * hdr["stride"]
    with open(path, "rb") as f:
        f.seek(off)
        end = parse_end(f.read(256))
    return None if end is None else (off, end[0], end[1])


def aborted_reason(path, hdr=None):
    """Why the producer of the stream file at `path` aborted it: the reason in the end record
    after the last whole record, REASON_NOT_RECORDED when only the header is marked, or None if it
    was not aborted."""
    if hdr is None:
        with open(path, "rb") as f:
            hdr = parse_header(f.read(4096))
    n = max(os.path.getsize(path) - 4096, 0) // hdr["stride"]
    end = _end_after(path, hdr, n)
    if end is not None:
        return end[2]
    return REASON_NOT_RECORDED if hdr["aborted"] else None


def black_level_values(hdr, black):
    """Black level (header field, DN of the payload format) in the units unpack() returns:
    MSB-aligned Mono16 is shifted down by 16 - bits_valid, other formats are unchanged."""
    if hdr["pixel_format"] == "Mono16" and hdr["msb_aligned"]:
        return black / float(1 << (16 - hdr["bits_valid"]))
    return black


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
    elif fmt in ("Mono12p", "Mono12Packed"):
        pad = np.zeros(-len(b) % 3, np.uint8)
        g = np.concatenate([b, pad]).reshape(-1, 3).astype(np.uint16)
        if fmt == "Mono12p":
            p0 = g[:, 0] | ((g[:, 1] & 0x0F) << 8)
        else:
            p0 = (g[:, 0] << 4) | (g[:, 1] & 0x0F)
        p1 = (g[:, 1] >> 4) | (g[:, 2] << 4)
        v = np.stack([p0, p1], axis=1).reshape(-1)[:n]
    else:
        raise StreamError("no unpacking for %s" % fmt)
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


MAGIC5 = b"\x89PSNS"


def _frame_header_ok(b):
    return len(b) >= 256 and b[:8] == FRAME_MAGIC and \
        zlib.crc32(b[:252]) == struct.unpack_from("<I", b, 252)[0]


RECOVER_SCAN_MAX = 256 << 20
DEFAULT_ANGLES = [90, 45, 135, 0]


def _frames_in(buf, want):
    """(offset, index, payload_crc) of the first `want` frame headers with a valid CRC."""
    out, frm = [], 0
    while len(out) < want:
        j = buf.find(FRAME_MAGIC, frm)
        if j < 0:
            break
        if j + 256 <= len(buf) and _frame_header_ok(buf[j:j + 256]):
            out.append((j, struct.unpack_from("<Q", buf, j + 8)[0],
                        struct.unpack_from("<I", buf, j + 20)[0]))
        frm = j + 1
    return out


def recover_header(buf, eof, damage, width=None, height=None, pixel_format=None):
    """Degraded mode (docs/stream-format.md, "Degraded mode"): infers the header of a stream whose
    file header is damaged from the frames found in `buf` (the start of the stream; `eof` if it is
    all of it), as the Rust StreamReader::new_recovering does. Returns (header dict, start offset);
    the dict's "recovered" key says how. Raises StreamError if the geometry cannot be inferred."""
    buf = bytes(buf)
    hb = buf[:4096].ljust(4096, b"\0")
    w_s, h_s, code_s = struct.unpack_from("<III", hb, 20)
    p_s, s_s = struct.unpack_from("<QQ", hb, 48)
    found = _frames_in(buf, 3)
    how, stride = [], None
    if len(found) >= 2:
        (a, ia, _), (b, ib, _) = found[:2]
        if ib > ia and (b - a) % (ib - ia) == 0 and ((b - a) // (ib - ia)) % 4096 == 0:
            stride = (b - a) // (ib - ia)
            how.append("stride %d B between frames %d and %d" % (stride, ia, ib))
    if stride is None and found:
        a, ia, _ = found[0]
        if ia > 0 and a > 4096 and (a - 4096) % ia == 0 and ((a - 4096) // ia) % 4096 == 0:
            stride = (a - 4096) // ia
            how.append("stride %d B from frame %d at byte %d" % (stride, ia, a))
        elif ia == 0 and eof and len(found) == 1 and (len(buf) - a) % 4096 == 0 and len(buf) > a:
            stride = len(buf) - a
            how.append("stride %d B from the single frame's record" % stride)
    payload = None
    for pos, idx, pcrc in found:
        data = buf[pos + 256:]
        lo, hi = (max(0, stride - 4351), stride - 256) if stride else (0, min(len(data), MAX_PAYLOAD))
        hi = min(hi, len(data))
        if lo > hi:
            continue
        crc, hits = zlib.crc32(data[:lo]), []
        for n in range(lo, hi + 1):
            if n > lo:
                crc = zlib.crc32(data[n - 1:n], crc)
            if n > 0 and crc == pcrc:
                hits.append(n)
        if len(hits) == 1:
            payload = hits[0]
            how.append("payload %d B from the payload CRC of frame %d" % (payload, idx))
            stride = stride or stride_for(payload)
            break
    target = payload
    if target is None and stride_for(p_s) == (stride or s_s) and 0 < p_s <= MAX_PAYLOAD:
        target = p_s
        how.append("payload %d B from the header (fits the stride)" % p_s)
    fmts = [pixel_format] if pixel_format else list(CONTAINER_BITS)
    stored_fmt = PFNC.get(code_s)
    cands = {}
    if target is not None:
        for fmt in fmts:
            ws = width if width else w_s
            hs = height if height else h_s
            pairs = [(ws, hs)]
            for n in pixel_counts(fmt, target):
                if not width and hs and n % hs == 0:
                    pairs.append((n // hs, hs))
                if not height and ws and n % ws == 0:
                    pairs.append((ws, n // ws))
            for w, h in pairs:
                if 1 <= w <= 65535 and 1 <= h <= 65535 and payload_size(fmt, w, h) == target:
                    score = ((w == w_s) + (h == h_s) + (fmt == stored_fmt) + bool(width)
                             + bool(height) + bool(pixel_format))
                    cands[(fmt, w, h)] = score
    elif width and height and pixel_format:
        cands[(pixel_format, width, height)] = 3
    said = ("frames found: %d; stride %s; payload %s; header fields say %d x %d, PFNC 0x%08X"
            % (len(found), stride, target, w_s, h_s, code_s))
    ranked = sorted(cands.items(), key=lambda kv: -kv[1])
    if not ranked:
        raise StreamError("%s; cannot infer the frame geometry (%s): give width, height and "
                          "pixel format" % (damage, said))
    if len(ranked) > 1 and ranked[0][1] == ranked[1][1]:
        raise StreamError("%s; frame geometry ambiguous (%s or %s; %s): give width, height and "
                          "pixel format" % (damage, ranked[0][0], ranked[1][0], said))
    if ranked[0][1] < 2:
        raise StreamError("%s; the geometry that fits the frames disagrees with more than one "
                          "header field (%s): give width, height and pixel format" % (damage, said))
    fmt, w, h = ranked[0][0]
    p = payload_size(fmt, w, h)
    if stride and stride_for(p) != stride:
        raise StreamError("%s; %d x %d %s has stride %d B but the frames found are %d B apart"
                          % (damage, w, h, fmt, stride_for(p), stride))
    for name, given, same in (("width", width, w == w_s), ("height", height, h == h_s),
                              ("pixel format", pixel_format, fmt == stored_fmt)):
        how.append("%s %s" % (name, "given" if given else "from the header" if same
                              else "inferred (header field disagrees)"))
    defaults = []
    bits, align = struct.unpack_from("<HH", hb, 32)
    if not (bits == 8 if fmt == "Mono8" else 1 <= bits <= CONTAINER_BITS[fmt]):
        defaults.append("bits valid (%d -> %d)" % (bits, CONTAINER_BITS[fmt]))
        bits = CONTAINER_BITS[fmt]
    if align > 1 or (align == 1 and fmt != "Mono16"):
        defaults.append("alignment (%d -> LSB)" % align)
        align = 0
    angles = list(struct.unpack_from("<4h", hb, 36))
    if sorted(angles) != [0, 45, 90, 135]:
        defaults.append("polarizer angles (IMX250MZR 90, 45, 135, 0)")
        angles = DEFAULT_ANGLES
    sense = struct.unpack_from("<h", hb, 44)[0]
    if sense not in (1, -1):
        defaults.append("angle sense (%d -> +1)" % sense)
        sense = 1
    strs = []
    for off, what in ((160, "producer"), (192, "preset")):
        try:
            strs.append(_cstr(hb[off:off + 32], what))
        except StreamError:
            defaults.append("%s (empty)" % what)
            strs.append("")
    jo, jl = struct.unpack_from("<II", hb, 224)
    js = ""
    if (jo, jl) != (0, 0):
        try:
            if jo < 232 or jo + jl > 4092:
                raise ValueError
            js = hb[jo:jo + jl].decode()
            if "\0" in js:
                raise ValueError
        except ValueError:
            defaults.append("JSON (dropped)")
            js = ""
    major, minor = struct.unpack_from("<HH", hb, 8)
    code = {v: k for k, v in PFNC.items()}[fmt]
    seed = struct.unpack_from("<Q", hb, 72)[0]
    info = ("%s; geometry %d x %d %s (payload %d B, stride %d B): %s"
            % (damage, w, h, fmt, p, stride_for(p), ", ".join(how)))
    if defaults:
        info += "; defaults used for " + ", ".join(defaults)
    hdr = dict(version=(1, minor), width=w, height=h, pfnc=code, pixel_format=fmt,
               bits_valid=bits, msb_aligned=bool(align), angles_deg=angles, angle_sense=sense,
               payload_size=p, stride=stride_for(p), frame_count=0,
               aborted=struct.unpack_from("<H", hb, 46)[0] == 1, seed=seed,
               camera=dict(zip(CAMERA, struct.unpack_from("<10d", hb, 80))), producer=strs[0],
               preset=strs[1], json=js, recovered=info)
    start = min(found[0][0], 4096) if found else 4096
    return hdr, min(start, len(buf))


def iter_events(f, recover=False, width=None, height=None, pixel_format=None):
    """Yields the reader's events from a binary file object (file, FIFO, stdin), as the Rust
    StreamReader (src/stream/reader/) does:
      ("frame", meta, values, payload_crc_ok, offset)
      ("gap", first_missing, next_present)              frames first..next-1 dropped upstream
      ("corrupt", index_or_None, offset, reason)        damaged record, or index not increasing
      ("truncated", index_or_None, offset, have, need)  partial record (EOF or producer died)
      ("skipped", offset, bytes)                        bytes skipped while resynchronising
      ("restart", header)                               new file header; layout may change
      ("aborted", offset, frames, reason)               end record: the producer stopped because
                                                        of a failure (bad input, I/O, a signal)
      ("recovered", header)                             degraded mode: first event, the inferred
                                                        header (header["recovered"] says how)
    The first file header is read first and raises StreamError if it is unusable, unless
    recover=True: then a damaged header is replaced as recover_header() infers it (width,
    height, pixel_format: the user's geometry, if known)."""
    st = dict(buf=bytearray(), start=0, off=0, eof=False)

    def avail():
        return len(st["buf"]) - st["start"]

    def view(a=0, b=None):
        s = st["start"]
        return bytes(st["buf"][s + a:len(st["buf"]) if b is None else s + b])

    def fill(n):
        while avail() < n and not st["eof"]:
            if st["start"]:
                del st["buf"][:st["start"]]
                st["start"] = 0
            c = f.read(max(n - avail(), 1 << 16))
            if not c:
                st["eof"] = True
            else:
                st["buf"].extend(c)

    def consume(n):
        n = min(n, avail())
        st["start"] += n
        st["off"] += n

    def find(lo, hi=None):
        s = st["start"]
        i = st["buf"].find(MAGIC5, s + lo, len(st["buf"]) if hi is None else s + hi)
        return -1 if i < 0 else i - s

    def valid_at(j):
        fill(j + 8)
        if avail() < j + 8:
            return False
        m = view(j, j + 8)
        if m == END_MAGIC:
            fill(j + 256)
            return parse_end(view(j, j + 256)) is not None
        if m == FRAME_MAGIC:
            fill(j + 256)
            return _frame_header_ok(view(j, j + 256))
        if m == FILE_MAGIC:
            fill(j + 4096)
            if avail() < j + 4096:
                return False
            try:
                parse_header(view(j, j + 4096))
                return True
            except StreamError:
                return False
        return False

    def valid_magic_within(lo, hi):
        frm = lo
        while frm < hi:
            i = find(frm, hi)
            if i < 0 or i + 5 > hi:
                return None
            if valid_at(i):
                return i
            frm = i + 1
        return None

    fill(4096 + 8)
    try:
        hdr = parse_header(view(0, 4096))
        consume(4096)
    except StreamError as e:
        if not recover or avail() < 4096 or view(0, 8) != FILE_MAGIC and view(4096, 4104) != FRAME_MAGIC \
                and sum(x != y for x, y in zip(view(0, 8), FILE_MAGIC)) > 1:
            raise
        want = 4096 + (1 << 20)
        while True:
            fill(want)
            if st["eof"] or avail() >= RECOVER_SCAN_MAX or len(_frames_in(view(), 3)) >= 3:
                break
            want = min(want * 2, RECOVER_SCAN_MAX)
        hdr, start = recover_header(view(), st["eof"], "stream file header damaged (%s)" % e,
                                    width, height, pixel_format)
        yield ("recovered", hdr)
        consume(start)
    expected = 0  # next expected index; None right after a restart

    while True:
        fill(8)
        a = avail()
        if a == 0:
            return
        if a < 8:
            yield ("truncated", None, st["off"], a, hdr["stride"])
            return
        head = view(0, 8)
        reason = None
        if head == FRAME_MAGIC:
            fill(256)
            if avail() < 256:
                yield ("truncated", None, st["off"], avail(), hdr["stride"])
                return
            hb = view(0, 256)
            if not _frame_header_ok(hb):
                reason = "frame header CRC mismatch"
            else:
                index, pcrc = struct.unpack_from("<Q", hb, 8)[0], struct.unpack_from("<I", hb, 20)[0]
                stride, p = hdr["stride"], hdr["payload_size"]
                if expected is not None and index < expected:
                    # a valid header out of order (duplicate / spliced record): skip the record
                    yield ("corrupt", index, st["off"], "index %d not after %d" % (index, expected - 1))
                    fill(stride)
                    consume(stride)
                    continue
                fill(stride)
                if avail() < stride:
                    yield ("truncated", index, st["off"], avail(), stride)
                    return
                ok = zlib.crc32(view(256, 256 + p)) == pcrc
                if not ok:
                    # writer died mid-record and a new record (or file header) follows inside it?
                    j = valid_magic_within(256, stride)
                    if j is not None:
                        yield ("truncated", index, st["off"], j, stride)
                        expected = index + 1
                        consume(j)
                        continue
                n = stride
                if ok:
                    # a valid header inside the zero pad: the writer died in the pad
                    j = valid_magic_within(256 + p, stride)
                    if j is not None:
                        n = j
                rec = np.frombuffer(view(0, stride), frame_dtype(hdr))[0]
                if expected is not None and index > expected:
                    yield ("gap", expected, index)
                off = st["off"]
                expected = index + 1
                meta, values = _meta(rec), unpack(rec["payload"], hdr)
                consume(n)
                yield ("frame", meta, values, ok, off)
                continue
        elif head == END_MAGIC:
            fill(256)
            if avail() < 256:
                yield ("truncated", None, st["off"], avail(), hdr["stride"])
                return
            end = parse_end(view(0, 256))
            if end is None:
                reason = "end record invalid"
            else:
                off = st["off"]
                consume(256)
                yield ("aborted", off, end[0], end[1])
                continue
        elif head == FILE_MAGIC:
            fill(4096)
            if avail() < 4096:
                yield ("truncated", None, st["off"], avail(), hdr["stride"])
                return
            try:
                h2 = parse_header(view(0, 4096))
            except StreamError as e:
                reason = str(e)
            else:
                consume(4096)
                hdr = h2
                expected = None
                yield ("restart", h2)
                continue
        else:
            reason = "frame magic missing"
        # damage: scan for the next valid frame or file header, then account for what was lost
        p0, stride = st["off"], hdr["stride"]
        cands = []  # index fields of damaged records whose frame magic survived

        def note():
            if avail() >= 8 and view(0, 8) == FRAME_MAGIC:
                cands.append(struct.unpack_from("<Q", view(8, 16))[0] if avail() >= 16 else None)

        note()
        consume(1)
        end = None
        while True:
            fill(4096)
            if avail() == 0:
                end = "eof"
                break
            i = find(0)
            if i < 0:
                # keep 4 bytes: a magic may straddle the next refill (and is then found at 0)
                keep = 0 if st["eof"] else min(4, avail())
                consume(avail() - keep)
                if st["eof"]:
                    end = "eof"
                    break
            else:
                consume(i)
                if valid_at(0):
                    end = "frame" if view(0, 8) == FRAME_MAGIC else "header"
                    break
                note()
                consume(1)
        skipped = st["off"] - p0
        nxt = struct.unpack_from("<Q", view(8, 16))[0] if end == "frame" else None
        rounded = (skipped + stride // 2) // stride
        lo = hi = None
        if expected is not None:
            lo = expected
            if nxt is not None and nxt >= expected:
                hi = nxt
        n_damaged = max(len(cands), rounded)
        if lo is not None and hi is not None:
            n_damaged = min(n_damaged, hi - lo)
        ids = set()
        if lo is not None:
            for c in cands:
                if c is not None and c >= lo and (hi is None or c < hi) and len(ids) < n_damaged:
                    ids.add(c)
            i = lo
            while len(ids) < n_damaged and (hi is None or i < hi):
                ids.add(i)
                i += 1
        ids = sorted(ids)
        n_reports = len(ids) if lo is not None else n_damaged
        for k in range(n_reports):
            yield ("corrupt", ids[k] if k < len(ids) else None, p0 + k * stride, reason)
        if lo is not None and hi is not None:
            frm = lo
            for i in ids + [hi]:
                if i > frm:
                    yield ("gap", frm, i)
                frm = i + 1
            expected = hi
        elif lo is not None and ids:
            expected = max(ids[-1], lo) + 1
        if skipped:
            yield ("skipped", p0, skipped)
        if end == "eof":
            return


def iter_frames(f, report=None, **recover):
    """Yields (meta, values, payload_crc_ok) from a binary file object (file, FIFO, stdin).
    Everything else (damage, gaps, truncation, restarts) goes to report(str) (default: stderr);
    use iter_events() to see the header in force after a restart."""
    report = report or (lambda s: print(s, file=sys.stderr))
    for ev in iter_events(f, **recover):
        if ev[0] == "recovered":
            report("DEGRADED MODE: %s" % ev[1]["recovered"])
        elif ev[0] == "frame":
            _, meta, values, ok, _ = ev
            if not ok:
                report("frame %d: payload CRC mismatch" % meta["index"])
            yield meta, values, ok
        else:
            report(describe(ev))


def describe(ev):
    """One human-readable line for a non-frame event."""
    k = ev[0]
    idx = lambda i: "?" if i is None else str(i)  # noqa: E731
    if k == "gap":
        return "gap %d..%d: %d frames dropped" % (ev[1], ev[2], ev[2] - ev[1])
    if k == "corrupt":
        return "frame %s at byte %d corrupt: %s" % (idx(ev[1]), ev[2], ev[3])
    if k == "truncated":
        return "frame %s at byte %d truncated: %d of %d bytes" % (idx(ev[1]), ev[2], ev[3], ev[4])
    if k == "skipped":
        return "skipped %d bytes at byte %d" % (ev[2], ev[1])
    if k == "restart":
        return "producer restart"
    if k == "aborted":
        return "stream aborted by its producer: %s" % ev[3]
    return k


def canonical_event(ev):
    """Canonical line(s) of one event, as tests/stream/readers.rs prints the Rust reader's."""
    k = ev[0]
    idx = lambda i: "-" if i is None else str(i)  # noqa: E731
    if k == "frame":
        return canonical(ev[1], ev[2], ev[3])
    if k == "gap":
        return "gap %d..%d" % (ev[1], ev[2])
    if k == "corrupt":
        return "corrupt %s %d" % (idx(ev[1]), ev[2])
    if k == "truncated":
        return "truncated %s %d %d %d" % (idx(ev[1]), ev[2], ev[3], ev[4])
    if k == "skipped":
        return "skipped %d %d" % (ev[1], ev[2])
    if k == "aborted":
        return "aborted %d %d %s" % (ev[1], ev[2], ev[3])
    return "restart\n" + canonical_header(ev[1])


def _hex64(x):
    return "%016x" % struct.unpack("<Q", struct.pack("<d", x))[0]


def canonical(meta, values, ok):
    f64 = []
    for k in F64_ORDER:
        v = meta[k]
        f64 += v if isinstance(v, list) else [v]
    f32 = [meta["turbidity"], meta["albedo"]] + list(meta["class_fractions"])
    f32 = ["%08x" % struct.unpack("<I", struct.pack("<f", x))[0] for x in f32]
    v = np.ascontiguousarray(values, dtype="<u2")
    return "frame %d %d %d %d %d %d %s %s %s %d %08x" % (
        meta["index"], meta["flags"], int(ok), meta["exposure_start_ns"], meta["exposure_end_ns"],
        meta["host_time_ns"], ",".join(_hex64(x) for x in f64),
        ",".join(str(s) for s in meta["saturated"]), ",".join(f32), int(v.sum(dtype=np.uint64)),
        zlib.crc32(v.tobytes()))


def canonical_header(h):
    return "header %d %d %08x %d %d %d %d %d %d %s%s" % (
        h["width"], h["height"], h["pfnc"], h["bits_valid"], int(h["msb_aligned"]), h["seed"],
        h["frame_count"], h["payload_size"], h["stride"], ",".join(str(a) for a in h["angles_deg"]),
        " aborted" if h.get("aborted") else "")


def _recover_opts(argv):
    """Pops --recover, --width W, --height H, --pixel-format F from argv; returns iter_events kwargs."""
    kw, rest, i = {}, [], 0
    names = {"mono8": "Mono8", "mono12p": "Mono12p", "mono12packed": "Mono12Packed", "mono16": "Mono16"}
    while i < len(argv):
        a = argv[i]
        if a == "--recover":
            kw["recover"] = True
        elif a in ("--width", "--height", "--pixel-format") and i + 1 < len(argv):
            v = argv[i + 1]
            if a == "--pixel-format":
                if v.lower() not in names:
                    raise SystemExit("--pixel-format %s is not one of mono8, mono12p, mono12packed, "
                                     "mono16" % v)
                kw["pixel_format"] = names[v.lower()]
            else:
                kw[a[2:]] = int(v)
            i += 1
        else:
            rest.append(a)
        i += 1
    return kw, rest


def main(argv):
    kw, argv = _recover_opts(argv)
    if len(argv) < 3 or argv[1] not in ("info", "dump", "mmdump", "frame"):
        print(__doc__, file=sys.stderr)
        return 2
    cmd, path = argv[1], argv[2]
    f = sys.stdin.buffer if path == "-" else open(path, "rb")
    if cmd == "dump":
        head = f.read(4096)
        try:
            print(canonical_header(parse_header(head)))
        except StreamError as e:
            if not kw.get("recover"):
                print("not a valid psns stream header: %s (a damaged header: try --recover)" % e,
                      file=sys.stderr)
                return 1
        try:
            for ev in iter_events(_Prefixed(head, f), **kw):
                if ev[0] == "recovered":
                    print("DEGRADED MODE: %s" % ev[1]["recovered"], file=sys.stderr)
                    print(canonical_header(ev[1]))
                    continue
                print(canonical_event(ev))
        except StreamError as e:
            print("psns_stream.py: %s" % e, file=sys.stderr)
            return 1
        return 0
    if cmd == "mmdump":
        # numpy memmap path (regular files): whole records with a valid header, in file order
        hdr, frames = open_memmap(path)
        print(canonical_header(hdr))
        for rec in frames:
            hok, pok = check_frame(hdr, rec)
            if hok:
                print(canonical(_meta(rec), unpack(rec["payload"], hdr), pok))
        end = _end_after(path, hdr, len(frames))
        if end is not None:
            print(canonical_event(("aborted",) + end))
        return 0
    if cmd == "info":
        hdr, frames = open_memmap(path)
        out = dict(header=hdr, aborted=aborted_reason(path, hdr), frames=[])
        for rec in frames:
            hok, pok = check_frame(hdr, rec)
            m = _meta(rec) if hok else {}
            m.update(header_crc_ok=hok, payload_crc_ok=pok)
            out["frames"].append(m)
        print(json.dumps(out, indent=1))
        return 0
    n = int(argv[3])
    for meta, values, ok in iter_frames(f, **kw):
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
    try:
        status = main(sys.argv)
        sys.stdout.flush()
    except BrokenPipeError:
        # the reader of stdout went away (e.g. `| head`): end quietly, status 0 like `psns stream`;
        # stdout goes to /dev/null so the interpreter's final flush does not complain either
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        status = 0
    except StreamError as e:
        # a crafted or damaged header: a message, not a traceback
        print("psns_stream.py: not a valid psns stream: %s" % e, file=sys.stderr)
        status = 1
    except OSError as e:  # a missing file, a read error
        print("psns_stream.py: %s" % e, file=sys.stderr)
        status = 1
    except ValueError as e:  # a frame number that is not a number
        print("psns_stream.py: %s" % e, file=sys.stderr)
        status = 2
    except KeyboardInterrupt:
        # Ctrl-C: end quietly with the shell's status for SIGINT
        status = 130
    sys.exit(status)
