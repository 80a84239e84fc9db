"""A GenICam client of `psns gige` through Aravis's GObject introspection (Debian's
gir1.2-aravis-0.8 with python3-gi, run by /usr/bin/python3): what tests/gige/device.rs drives.

Every command prints JSON lines on stdout: one per buffer received ({"block": id, "status",
"sha256" of the image bytes, "width", "height", "pixel_format", "timestamp", "chunks"}) and a
last line {"stats": {...}} with the stream's counters.

    grab ADDR [--format F] [--frames N] [--packet-size B] [--region W,H,X,Y] [--chunks]
    trigger ADDR --count N [--interval S] [--format F]
    hold ADDR --seconds S [--heartbeat MS]   take control and keep it (or die without a word)
    settings ADDR                            read back features as JSON
"""

import argparse
import hashlib
import json
import sys
import time

import gi

gi.require_version("Aravis", "0.8")
from gi.repository import Aravis  # noqa: E402

# the chunk category's controls; its other features are the chunk data, read from the device
CHUNK_CONTROLS = ("ChunkModeActive", "ChunkSelector", "ChunkEnable")
STATS = [
    "n_completed_buffers",
    "n_failures",
    "n_underruns",
    "n_missing_frames",
    "n_received_packets",
    "n_missing_packets",
    "n_resend_requests",
    "n_resent_packets",
    "n_error_packets",
]


def emit(obj):
    print(json.dumps(obj), flush=True)


def image_bytes(buf):
    """The image part of a buffer: its first width * height * bits / 8 bytes (chunks follow)."""
    data = bytes(buf.get_data())
    bits = (buf.get_image_pixel_format() >> 16) & 0xFF
    n = buf.get_image_width() * buf.get_image_height() * bits // 8
    return data[:n]


def chunk_features(cam):
    """The chunk data features the device's GenICam describes: (name, is a float)."""
    gc = cam.get_device().get_genicam()
    names = gc.get_node("ChunkDataControl").get_features()
    return [(n, isinstance(gc.get_node(n), Aravis.GcFloat)) for n in names if n not in CHUNK_CONTROLS]


def describe(buf, parser=None, features=()):
    d = {
        "block": buf.get_frame_id(),
        "status": buf.get_status().value_nick,
        "timestamp": buf.get_timestamp(),
    }
    if buf.get_status() == Aravis.BufferStatus.SUCCESS:
        img = image_bytes(buf)
        d.update(
            sha256=hashlib.sha256(img).hexdigest(),
            size=len(img),
            width=buf.get_image_width(),
            height=buf.get_image_height(),
            offset_x=buf.get_image_x(),
            offset_y=buf.get_image_y(),
            pixel_format=buf.get_image_pixel_format(),
        )
        if parser is not None and buf.has_chunks():
            c = {
                n: parser.get_float_value(buf, n) if is_float else parser.get_integer_value(buf, n)
                for n, is_float in features
            }
            # floats as their exact bits, so the test compares them without rounding
            d["chunks"] = {k: (v.hex() if isinstance(v, float) else v) for k, v in c.items()}
    return d


def stats(stream):
    return {n: stream.get_info_uint64_by_name(n) for n in STATS}


def open_camera(args):
    cam = Aravis.Camera.new(args.address)
    cam.set_string("PixelFormat", args.format)
    if getattr(args, "packet_size", None):
        cam.gv_set_packet_size(args.packet_size)
    if getattr(args, "region", None):
        w, h, x, y = (int(v) for v in args.region.split(","))
        cam.set_region(x, y, w, h)
    return cam


def make_stream(cam, n):
    stream = cam.create_stream(None, None)
    payload = cam.get_payload()
    for _ in range(n):
        stream.push_buffer(Aravis.Buffer.new_allocate(payload))
    return stream


def grab(args):
    cam = open_camera(args)
    parser, features = None, []
    if args.chunks:
        # every chunk the device offers, and every feature it describes
        cam.set_chunks(",".join(cam.dup_available_enumerations_as_strings("ChunkSelector")))
        parser = cam.create_chunk_parser()
        features = chunk_features(cam)
    # exactly --frames blocks, with a buffer for each: none is lost to a slow reader
    cam.set_acquisition_mode(Aravis.AcquisitionMode.MULTI_FRAME)
    cam.set_integer("AcquisitionFrameCount", args.frames)
    stream = make_stream(cam, args.frames + 2)
    cam.start_acquisition()
    seen = 0
    deadline = time.monotonic() + args.timeout
    while seen < args.frames and time.monotonic() < deadline:
        buf = stream.timeout_pop_buffer(1_000_000)
        if buf is None:
            continue
        emit(describe(buf, parser, features))
        seen += 1
        stream.push_buffer(buf)
    cam.stop_acquisition()
    emit({"stats": stats(stream)})


def trigger(args):
    cam = open_camera(args)
    cam.set_acquisition_mode(Aravis.AcquisitionMode.CONTINUOUS)
    cam.set_trigger("Software")
    stream = make_stream(cam, args.count + 4)
    cam.start_acquisition()

    def drain(seconds):
        out = []
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            buf = stream.timeout_pop_buffer(50_000)
            if buf is not None:
                out.append(describe(buf))
                stream.push_buffer(buf)
        return out

    before = drain(1.0)
    emit({"frames_before_trigger": len(before), "before": before})
    for _ in range(args.count):
        cam.software_trigger()
        for d in drain(args.interval):
            emit(d)
    for d in drain(2.0):
        emit(d)
    cam.stop_acquisition()
    emit({"stats": stats(stream)})


def hold(args):
    cam = Aravis.Camera.new(args.address)
    if args.heartbeat:
        cam.set_integer("GevHeartbeatTimeout", args.heartbeat)
    cam.set_string("DeviceUserID", "holder")
    emit({"holding": True})
    time.sleep(args.seconds)


def settings(args):
    cam = Aravis.Camera.new(args.address)
    out = {}
    for name in ["Width", "Height", "OffsetX", "OffsetY", "PayloadSize", "AcquisitionFrameCount"]:
        out[name] = cam.get_integer(name)
    for name in ["PixelFormat", "AcquisitionMode", "TriggerMode", "DeviceUserID"]:
        out[name] = cam.get_string(name)
    for name in ["ExposureTime", "Gain", "BlackLevel", "AcquisitionFrameRate"]:
        out[name] = cam.get_float(name)
    emit(out)


def main():
    ap = argparse.ArgumentParser()
    sub = ap.add_subparsers(dest="cmd", required=True)
    g = sub.add_parser("grab")
    g.add_argument("address")
    g.add_argument("--format", default="Mono8")
    g.add_argument("--frames", type=int, default=5)
    g.add_argument("--packet-size", type=int, default=0)
    g.add_argument("--region")
    g.add_argument("--chunks", action="store_true")
    g.add_argument("--timeout", type=float, default=120.0)
    t = sub.add_parser("trigger")
    t.add_argument("address")
    t.add_argument("--format", default="Mono8")
    t.add_argument("--count", type=int, default=5)
    t.add_argument("--interval", type=float, default=0.4)
    h = sub.add_parser("hold")
    h.add_argument("address")
    h.add_argument("--seconds", type=float, default=30.0)
    h.add_argument("--heartbeat", type=int, default=0)
    s = sub.add_parser("settings")
    s.add_argument("address")
    args = ap.parse_args()
    {"grab": grab, "trigger": trigger, "hold": hold, "settings": settings}[args.cmd](args)


if __name__ == "__main__":
    sys.exit(main())
