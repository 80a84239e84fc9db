"""Checks of psns's ROS 2 bags with readers nobody here wrote: rosbags (AnyReader, Humble type
store, serialize_cdr) and mcap + mcap-ros2-support (DecoderFactory). Run by tests/stream/ros2.rs with
the test venv's interpreter; every check is an assert, and the last line says what was checked.

    ros2_check.py cdr CASES.json          rosbags' CDR and msgdef of each case, as JSON lines
    ros2_check.py bag BAG STREAM [--truth] a bag (rosbag2 dir or .mcap) against a psns stream
    ros2_check.py truth BAG DIR           frame 0's truth images against DIR/truth_*.npy
    ros2_check.py unfinished BAG          both readers refuse or flag the bag
    ros2_check.py recovered BAG STREAM    a bag psns recover finished: every topic holds the
                                          first messages of the stream's frames, one frame's
                                          messages at most cut off at its end
    ros2_check.py chunks MCAP             the topics of each chunk, one line per chunk
"""

import json
import math
import sys
from pathlib import Path

import numpy as np
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "tools"))
import psns_stream  # noqa: E402

TS = get_typestore(Stores.ROS2_HUMBLE)
TOPICS = {
    "/psns/image_raw": "sensor_msgs/msg/Image",
    "/psns/camera_info": "sensor_msgs/msg/CameraInfo",
    "/psns/pose": "geometry_msgs/msg/PoseStamped",
    "/psns/sun": "geometry_msgs/msg/Vector3Stamped",
    "/tf": "tf2_msgs/msg/TFMessage",
}
TRUTH = {"/psns/truth/dolp": "sensor_msgs/msg/Image", "/psns/truth/aolp": "sensor_msgs/msg/Image"}
CLASSES = {"/psns/truth/classes": "std_msgs/msg/Float64MultiArray"}
CLASS_NAMES = "outside,sky,cloud,obstruction,ground,sun"
FLAG_CLASSES = 1 << 8


def T(name):
    return TS.types[name]


def make(kind, v):
    """A rosbags message from the JSON description the Rust test wrote."""
    Time, Header = T("builtin_interfaces/msg/Time"), T("std_msgs/msg/Header")

    def header(h):
        return Header(stamp=Time(sec=h["sec"], nanosec=h["nanosec"]), frame_id=h["frame_id"])

    if kind == "time":
        return Time(sec=v["sec"], nanosec=v["nanosec"])
    if kind == "header":
        return header(v)
    if kind == "image":
        return T("sensor_msgs/msg/Image")(
            header=header(v["header"]), height=v["height"], width=v["width"],
            encoding=v["encoding"], is_bigendian=0, step=v["step"],
            data=np.array(v["data"], dtype=np.uint8))
    if kind == "camera_info":
        roi = T("sensor_msgs/msg/RegionOfInterest")(
            x_offset=0, y_offset=0, height=0, width=0, do_rectify=False)
        return T("sensor_msgs/msg/CameraInfo")(
            header=header(v["header"]), height=v["height"], width=v["width"],
            distortion_model=v["distortion_model"], d=np.array(v["d"], dtype=np.float64),
            k=np.array(v["k"], dtype=np.float64), r=np.array(v["r"], dtype=np.float64),
            p=np.array(v["p"], dtype=np.float64), binning_x=0, binning_y=0, roi=roi)
    if kind == "pose":
        G = "geometry_msgs/msg/"
        x, y, z, w = v["orientation_xyzw"]
        pose = T(G + "Pose")(position=T(G + "Point")(x=v["position"][0], y=v["position"][1],
                                                      z=v["position"][2]),
                             orientation=T(G + "Quaternion")(x=x, y=y, z=z, w=w))
        return T(G + "PoseStamped")(header=header(v["header"]), pose=pose)
    if kind == "tf":
        G = "geometry_msgs/msg/"
        tfs = []
        for t in v["transforms"]:
            x, y, z, w = t["rotation_xyzw"]
            tr = T(G + "Transform")(translation=T(G + "Vector3")(*t["translation"]),
                                    rotation=T(G + "Quaternion")(x=x, y=y, z=z, w=w))
            tfs.append(T(G + "TransformStamped")(header=header(t["header"]),
                                                 child_frame_id=t["child_frame_id"], transform=tr))
        return T("tf2_msgs/msg/TFMessage")(transforms=tfs)
    if kind == "float64_array":
        S = "std_msgs/msg/"
        dim = T(S + "MultiArrayDimension")(label=v["label"], size=len(v["data"]),
                                            stride=len(v["data"]))
        return T(S + "Float64MultiArray")(layout=T(S + "MultiArrayLayout")(dim=[dim], data_offset=0),
                                          data=np.array(v["data"], dtype=np.float64))
    if kind == "vector3":
        x, y, z = v["vector"]
        return T("geometry_msgs/msg/Vector3Stamped")(
            header=header(v["header"]), vector=T("geometry_msgs/msg/Vector3")(x=x, y=y, z=z))
    raise ValueError(kind)


def cmd_cdr(path):
    cases = json.loads(Path(path).read_text())
    for c in cases:
        msg = make(c["kind"], c["value"])
        cdr = TS.serialize_cdr(msg, msg.__msgtype__)
        msgdef, _ = TS.generate_msgdef(msg.__msgtype__, ros_version=2)
        print(json.dumps({"type": msg.__msgtype__, "cdr": bytes(cdr).hex(), "msgdef": msgdef}))


def stream_frames(path):
    with open(path, "rb") as f:
        hdr = psns_stream.parse_header(f.read(4096))
    with open(path, "rb") as f:
        frames = list(psns_stream.iter_frames(f))
    assert frames and all(ok for _, _, ok in frames), "the stream has damaged frames"
    return hdr, frames


def stamp_ns(h):
    return h.stamp.sec * 1_000_000_000 + h.stamp.nanosec


def read_rosbags(bag):
    out = {}
    with AnyReader([Path(bag)], default_typestore=TS) as r:
        conns = {c.topic: (c.msgtype, c.msgcount) for c in r.connections}
        for c, t, raw in r.messages():
            out.setdefault(c.topic, []).append((t, r.deserialize(raw, c.msgtype)))
        times = [t for v in out.values() for t, _ in v]
        # the bag's own summary (metadata.yaml, or the MCAP statistics) agrees with the messages
        assert r.message_count == len(times), (r.message_count, len(times))
        assert (r.start_time, r.end_time) == (min(times), max(times) + 1), (r.start_time, r.end_time)
    return conns, out


def read_mcap(path):
    out, conns = {}, {}
    with open(path, "rb") as f:
        rd = make_reader(f, decoder_factories=[DecoderFactory()])
        header = rd.get_header()
        assert header.profile == "ros2", header
        summary = rd.get_summary()
        for ch in summary.channels.values():
            sch = summary.schemas[ch.schema_id]
            assert ch.message_encoding == "cdr" and sch.encoding == "ros2msg", (ch, sch)
            assert "offered_qos_profiles" in ch.metadata
            conns[ch.topic] = (sch.name, summary.statistics.channel_message_counts[ch.id])
        for sch, ch, msg, dec in rd.iter_decoded_messages(log_time_order=True):
            assert msg.log_time == msg.publish_time
            out.setdefault(ch.topic, []).append((msg.log_time, dec))
    return conns, out


def check_frames(reader, conns, msgs, hdr, frames, want_topics):
    n = len(frames)
    assert conns == {k: (v, n) for k, v in want_topics.items()}, (reader, conns)
    cam = hdr["camera"]
    f_px = cam["focal_length_mm"] * 1000.0 / cam["pixel_pitch_um"]
    cx, cy = cam["principal_col"], cam["principal_row"]
    mono8 = hdr["pixel_format"] == "Mono8"
    for k, (meta, values, _) in enumerate(frames):
        t0 = meta["exposure_start_ns"]
        for topic in want_topics:
            t, m = msgs[topic][k]
            if topic in CLASSES:
                # no header: the log time is the stamp; the values are the stream header's
                assert t == t0, (reader, topic, k, t, t0)
                dims = m.layout.dim
                assert len(dims) == 1 and dims[0].label == CLASS_NAMES, dims
                assert dims[0].size == dims[0].stride == 6 and m.layout.data_offset == 0
                want = np.array(meta["class_fractions"], dtype=np.float32).astype(np.float64)
                assert np.array_equal(np.asarray(m.data), want), (reader, k, m.data, want)
                assert abs(float(np.sum(want)) - 1.0) < 1e-5, want
                continue
            h = m.transforms[0].header if topic == "/tf" else m.header
            assert t == t0 == stamp_ns(h), (reader, topic, k, t, t0)
        _, im = msgs["/psns/image_raw"][k]
        assert im.header.frame_id == "psns_camera_optical"
        assert (im.height, im.width) == (hdr["height"], hdr["width"])
        assert im.is_bigendian == 0
        want = values.astype(np.uint8) if mono8 else values.astype("<u2")
        assert im.encoding == ("mono8" if mono8 else "mono16"), im.encoding
        assert im.step == hdr["width"] * (1 if mono8 else 2)
        assert bytes(im.data) == want.tobytes(), (reader, "pixels of frame", k)
        _, ci = msgs["/psns/camera_info"][k]
        assert ci.header.frame_id == "psns_camera_optical"
        assert (ci.height, ci.width) == (hdr["height"], hdr["width"])
        assert list(ci.k) == [f_px, 0.0, cx, 0.0, f_px, cy, 0.0, 0.0, 1.0], list(ci.k)
        assert list(ci.p) == [f_px, 0.0, cx, 0.0, 0.0, f_px, cy, 0.0, 0.0, 0.0, 1.0, 0.0]
        assert list(ci.r) == [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
        proj = json.loads(hdr["json"])["optics"]["projection"]
        if proj == "rectilinear":
            assert ci.distortion_model == "plumb_bob" and list(ci.d) == [0.0] * 5
        else:
            assert ci.distortion_model == "equidistant" and len(ci.d) == 4
        _, p = msgs["/psns/pose"][k]
        assert p.header.frame_id == "enu"
        w, x, y, z = meta["attitude_wxyz"]
        o = p.pose.orientation
        assert [o.x, o.y, o.z, o.w] == [x, y, z, w], (k, o, meta["attitude_wxyz"])
        assert [p.pose.position.x, p.pose.position.y, p.pose.position.z] == [0.0, 0.0, 0.0]
        _, s = msgs["/psns/sun"][k]
        assert s.header.frame_id == "enu"
        az, el = math.radians(meta["sun_azimuth_deg"]), math.radians(meta["sun_elevation_deg"])
        sv = [math.cos(el) * math.sin(az), math.cos(el) * math.cos(az), math.sin(el)]
        got = [s.vector.x, s.vector.y, s.vector.z]
        assert max(abs(a - b) for a, b in zip(got, sv)) < 1e-12, (got, sv)
        assert abs(math.hypot(*got) - 1.0) < 1e-12
        _, tf = msgs["/tf"][k]
        assert len(tf.transforms) == 1, tf
        t = tf.transforms[0]
        assert (t.header.frame_id, t.child_frame_id) == ("enu", "psns_camera_optical"), t
        assert stamp_ns(t.header) == t0
        r, tr = t.transform.rotation, t.transform.translation
        assert [r.x, r.y, r.z, r.w] == [x, y, z, w], (k, r, meta["attitude_wxyz"])
        assert [tr.x, tr.y, tr.z] == [0.0, 0.0, 0.0]
        # the sun in the camera frame, turned into ENU by the pose, is the ENU sun
        q = np.array([w, x, y, z])
        rot = quat_matrix(q)
        assert np.abs(rot @ np.array(meta["sun_camera"]) - np.array(sv)).max() < 1e-9


def quat_matrix(q):
    w, x, y, z = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def cmd_bag(bag, stream, truth=False):
    hdr, frames = stream_frames(stream)
    want = dict(TOPICS, **(TRUTH if truth else {}))
    if all(meta["flags"] & FLAG_CLASSES for meta, _, _ in frames):
        want.update(CLASSES)
    else:
        assert not any(meta["flags"] & FLAG_CLASSES for meta, _, _ in frames)
    bag = Path(bag)
    mcap_file = bag if bag.suffix == ".mcap" else next(bag.glob("*.mcap"))
    if bag.is_dir():
        conns, msgs = read_rosbags(bag)
        check_frames("rosbags", conns, msgs, hdr, frames, want)
    conns, msgs = read_mcap(mcap_file)
    check_frames("mcap", conns, msgs, hdr, frames, want)
    if not bag.is_dir():
        # a bare MCAP file: rosbags reads it too (its MCAP storage, without metadata.yaml)
        conns, msgs = read_rosbags(bag)
        check_frames("rosbags", conns, msgs, hdr, frames, want)
    if truth:
        for topic in TRUTH:
            for _, im in msgs[topic]:
                assert im.encoding == "32FC1" and im.step == 4 * hdr["width"], im.encoding
                assert im.header.frame_id == "psns_camera_optical"
    print(f"ok: {len(frames)} frames, {len(want)} topics, both readers")


def cmd_truth(bag, npy_dir):
    _, msgs = read_rosbags(bag)
    d = Path(npy_dir)
    for topic, name in (("/psns/truth/dolp", "truth_dolp.npy"), ("/psns/truth/aolp", "truth_aolp.npy")):
        _, im = msgs[topic][0]
        got = np.frombuffer(bytes(im.data), "<f4").reshape(im.height, im.width)
        want = np.load(d / name)
        assert got.shape == want.shape, (got.shape, want.shape)
        diff = np.abs(got.astype(np.float64) - want)
        if "aolp" in name:
            diff = np.minimum(diff, 180.0 - diff)
        assert diff.max() <= (1e-4 if "dolp" in name else 1e-2), (name, diff.max())
        assert np.count_nonzero(want) > want.size // 2, name
    print("ok: truth images equal render --raw's")


def cmd_unfinished(bag):
    bag = Path(bag)
    errors = []
    try:
        read_rosbags(bag)
    except Exception as e:  # noqa: BLE001 - any refusal counts; a silent read does not
        errors.append(f"rosbags: {type(e).__name__}: {e}")
    else:
        raise AssertionError("rosbags read the unfinished bag without complaint")
    files = [bag] if bag.is_file() else sorted(bag.glob("*.mcap"))
    for f in files:
        try:
            read_mcap(f)
        except Exception as e:  # noqa: BLE001
            errors.append(f"mcap: {type(e).__name__}: {e}")
        else:
            raise AssertionError(f"mcap read the unfinished {f} without complaint")
    print("refused: " + " | ".join(errors))


def cmd_recovered(bag, stream):
    hdr, frames = stream_frames(stream)
    bag = Path(bag)
    mcap_file = bag if bag.suffix == ".mcap" else next(bag.glob("*.mcap"))
    for reader, (conns, msgs) in (("rosbags", read_rosbags(bag)), ("mcap", read_mcap(mcap_file))):
        assert set(conns) == set(TOPICS), (reader, conns)
        counts = [conns[t][1] for t in TOPICS]
        # a frame's messages go in topic order, so a kill leaves each topic at most one behind
        # the one before it
        assert all(a - b in (0, 1) for a, b in zip(counts, counts[1:])), (reader, counts)
        assert counts[0] - counts[-1] <= 1 and counts[-1] > 0, (reader, counts)
        n = counts[-1]
        assert len(frames) >= counts[0], (reader, len(frames), counts)
        whole = {t: msgs[t][:n] for t in TOPICS}
        check_frames(reader, {t: (ty, n) for t, ty in TOPICS.items()}, whole, hdr, frames[:n], TOPICS)
        # the messages past the last whole frame are that frame's too
        for t in TOPICS:
            for k, (tm, _) in enumerate(msgs[t][n:], n):
                assert tm == frames[k][0]["exposure_start_ns"], (reader, t, k)
    print(f"ok: {n} whole frames, {counts[0]} images, both readers")


def cmd_chunks(path):
    from mcap.records import Chunk, Message
    from mcap.stream_reader import StreamReader, breakup_chunk
    with open(path, "rb") as f:
        names = {}
        for rec in StreamReader(f, emit_chunks=True).records:
            if isinstance(rec, Chunk):
                topics = []
                for r in breakup_chunk(rec):
                    if hasattr(r, "topic"):
                        names[r.id] = r.topic
                    if isinstance(r, Message):
                        topics.append(names[r.channel_id])
                print(" ".join(topics))


if __name__ == "__main__":
    cmd, *args = sys.argv[1:]
    if cmd == "cdr":
        cmd_cdr(*args)
    elif cmd == "bag":
        cmd_bag(args[0], args[1], truth="--truth" in args)
    elif cmd == "truth":
        cmd_truth(*args)
    elif cmd == "unfinished":
        cmd_unfinished(*args)
    elif cmd == "recovered":
        cmd_recovered(*args)
    elif cmd == "chunks":
        cmd_chunks(*args)
    else:
        sys.exit(f"unknown command {cmd}")
