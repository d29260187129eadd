#!/usr/bin/env python3
"""ROS 2 bag fixtures for tests/ros2_bag.rs, made and checked by an independent peer: the
`rosbags` package (pure Python, no ROS install), version pinned below.

    python3 -m venv /tmp/rosbags-venv
    /tmp/rosbags-venv/bin/pip install --only-binary=:all: rosbags==0.11.9
    /tmp/rosbags-venv/bin/python scripts/gen_ros2_fixture.py            # write imu.mcap, imu.csv
    DRIFTLESS_BLESS=1 cargo test --test ros2_bag committed               # rewrite written.mcap
    /tmp/rosbags-venv/bin/python scripts/gen_ros2_fixture.py check \\
        tests/fixtures/ros2/written.mcap > tests/fixtures/ros2/written.json

Run from the repository root; `cargo test` itself never needs Python.

`gen` (the default) writes tests/fixtures/ros2/imu.mcap, a rosbag2 MCAP file as rosbags writes
it (zstd chunks, profile ros2, rosbags' own ros2msg definitions), and metadata.yaml, the
rosbag2 directory's metadata rosbags writes beside it (the test makes a bag directory of the
two). Topics: `/imu/data`, sensor_msgs/msg/Imu, 1,800 messages at 100 Hz, frame_id imu_link,
values from scripts/splitmix.py (see `imu_message`); `/chatter`, std_msgs/msg/String, every
tenth step, so that topic selection is exercised. The log time is the stamp plus a varying
delay, as a recorder's receive time would be, so a reader that took the log time for the
stamp fails. imu.csv holds what a reader must decode: stamp_ns and angular_velocity x, y, z
as repr() (exact doubles); the other fields follow from the formulas in `imu_message`.

`recorded PATH [INPUT]` reads tests/fixtures/ros2/recorded.mcap, what `driftless record --format
ros2` recorded of a daemon replaying accel.mcap (tests/record.rs, the round trip, writes it under
DRIFTLESS_BLESS=1), with rosbags' reader and deserializer: every message of every topic,
asserting what the message definition asks (header.frame_id set, orientation "not provided"
(-1), a finite diagonal angular_velocity_covariance, stamps rising) and the accelerometer as
INPUT gave it (see `accel` below), and prints per topic the count, the stamps and a SHA-256
over every message's stamp, angular velocity, linear acceleration and covariance bytes; the
test computes the same from its own reading:

    /tmp/rosbags-venv/bin/python scripts/gen_ros2_fixture.py recorded \
        tests/fixtures/ros2/recorded.mcap > tests/fixtures/ros2/recorded.json

`accel` writes tests/fixtures/ros2/accel.mcap for the accelerometer's round trip
(tests/record.rs): `/imu/data` (Imu, 600 messages at 100 Hz, frame_id imu_link) whose
linear_acceleration varies per message (splitmix doubles around gravity on z) with a covariance
diag(1e-4, 2e-4, 3e-4), except messages 300-309, whose covariance element 0 is -1 ("not
provided": a driver that lost its accelerometer; their values are still written, so a reader
that ignores the -1 shows). accel.csv holds what a reader must decode: stamp_ns, ax, ay, az as
repr() and provided (1 or 0).

    /tmp/rosbags-venv/bin/python scripts/gen_ros2_fixture.py accel

`recorded` checks each recorded message's linear_acceleration against the input bag's message
of the same stamp (INPUT, default tests/fixtures/ros2/accel.mcap): bit for bit with a finite
diagonal covariance where the input provided one, "not provided" (-1) where it did not.

`odom` writes tests/fixtures/ros2/odom.mcap for tests/logged_stops.rs: `/imu/data` (Imu,
1,500 messages at 100 Hz: a gyro at rest with a bias of 0.4, -0.2, 0.1 deg/s and a small
splitmix wobble, in rad/s) and `/odom` (nav_msgs/msg/Odometry at 20 Hz, stamped 3 ms after
an Imu stamp): moving at 1.5 m/s (twist.twist.linear.x) for the first 5 s, standing (0, with
a 0.004 m/s jitter on y) for the next 5 s, then silent. odom.csv holds each Odometry
message's stamp_ns and speed, as a reader must decode them.

    /tmp/rosbags-venv/bin/python scripts/gen_ros2_fixture.py odom

`check PATH` reads an MCAP file that driftless's writer wrote (tests/ros2_bag.rs makes
written.mcap: `written_messages` there is `written_message` here) with rosbags' reader and
deserializer, asserts every field of every message against the same formulas, and prints
what it read as JSON; the test compares its own reading of the file with that JSON.
"""

import csv
import hashlib
import importlib.metadata
import json
import os
import shutil
import struct
import sys
import tempfile

import numpy as np
from rosbags.interfaces import Qos, QosDurability, QosHistory, QosLiveliness, QosReliability
from rosbags.interfaces import QosTime
from rosbags.rosbag2 import Reader, Writer
from rosbags.rosbag2.enums import CompressionFormat, CompressionMode, StoragePlugin
from rosbags.typesys import Stores, get_typestore

from splitmix import splitmix64  # scripts/splitmix.py

VERSION = "0.11.9"
assert importlib.metadata.version("rosbags") == VERSION, "pin rosbags==" + VERSION

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests", "fixtures", "ros2")
STORE = get_typestore(Stores.ROS2_JAZZY)
IMU = "sensor_msgs/msg/Imu"

# Stamps: 2023-11-14T22:13:20.123456789Z and on, every 10 ms.
T0_NS = 1_700_000_000_123_456_789
STEP_NS = 10_000_000
COUNT = 1800  # 18 s; with imu.csv, under 300 KB of fixtures
SEED = 30  # issue 30

# Infinite durations as rmw reports them (RMW_DURATION_INFINITE).
INFINITE = QosTime(9223372036, 854775807)
RELIABLE_KEEP_LAST_10 = Qos(
    QosHistory.KEEP_LAST,
    10,
    QosReliability.RELIABLE,
    QosDurability.VOLATILE,
    INFINITE,
    INFINITE,
    QosLiveliness.AUTOMATIC,
    INFINITE,
    False,
)


def diag(a, b, c):
    return np.array([a, 0.0, 0.0, 0.0, b, 0.0, 0.0, 0.0, c], dtype=np.float64)


def imu_message(k, u):
    """Message k of /imu/data; u yields the splitmix doubles (3 per message, x, y, z)."""
    types = STORE.types
    stamp = T0_NS + k * STEP_NS
    gyro = [b + 0.02 * (next(u) - 0.5) for b in (0.011, -0.007, 0.003)]
    return types[IMU](
        header=types["std_msgs/msg/Header"](
            stamp=types["builtin_interfaces/msg/Time"](
                sec=stamp // 1_000_000_000, nanosec=stamp % 1_000_000_000
            ),
            frame_id="imu_link",
        ),
        # A unit quaternion of exact, distinct components, so a swapped field shows.
        orientation=types["geometry_msgs/msg/Quaternion"](x=0.48, y=0.6, z=0.0, w=0.64),
        orientation_covariance=diag(0.01, 0.02, 0.03),
        angular_velocity=types["geometry_msgs/msg/Vector3"](x=gyro[0], y=gyro[1], z=gyro[2]),
        angular_velocity_covariance=diag(1e-6, 2e-6, 3e-6),
        # Constant (random values would double the file), distinct per axis.
        linear_acceleration=types["geometry_msgs/msg/Vector3"](x=0.125, y=-0.25, z=9.80665),
        linear_acceleration_covariance=diag(1e-4, 1e-4, 1e-4),
    ), stamp


def gen():
    tmp = tempfile.mkdtemp()
    try:
        bag = os.path.join(tmp, "imu")
        rows = []
        writer = Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP)
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        with writer:
            imu = writer.add_connection(
                "/imu/data", IMU, typestore=STORE, offered_qos_profiles=[RELIABLE_KEEP_LAST_10]
            )
            chatter = writer.add_connection(
                "/chatter",
                "std_msgs/msg/String",
                typestore=STORE,
                offered_qos_profiles=[RELIABLE_KEEP_LAST_10],
            )
            u = splitmix64(SEED)
            for k in range(COUNT):
                msg, stamp = imu_message(k, u)
                # A receive time: the stamp plus 1.0-1.6 ms.
                log_time = stamp + 1_000_000 + (k % 7) * 100_000
                writer.write(imu, log_time, bytes(STORE.serialize_cdr(msg, IMU)))
                rows.append([stamp] + [repr(v) for v in (
                    msg.angular_velocity.x, msg.angular_velocity.y, msg.angular_velocity.z)])
                if k % 10 == 5:
                    text = STORE.types["std_msgs/msg/String"](data=f"tick {k}")
                    writer.write(
                        chatter,
                        log_time + 50_000,
                        bytes(STORE.serialize_cdr(text, "std_msgs/msg/String")),
                    )
        os.makedirs(HERE, exist_ok=True)
        shutil.copyfile(os.path.join(bag, "imu.mcap"), os.path.join(HERE, "imu.mcap"))
        shutil.copyfile(os.path.join(bag, "metadata.yaml"), os.path.join(HERE, "metadata.yaml"))
    finally:
        shutil.rmtree(tmp)
    with open(os.path.join(HERE, "imu.csv"), "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["stamp_ns", "wx", "wy", "wz"])
        w.writerows(rows)
    print("wrote imu.mcap, metadata.yaml, imu.csv in", os.path.normpath(HERE), COUNT, "messages")


# --- check: what driftless's writer wrote, read by rosbags --------------------------------

WRITTEN_COUNT = 200
WRITTEN_SEED = 7
WRITTEN_T0_NS = 1_700_000_000_000_000_000
WRITTEN_STEP_NS = 5_000_000  # 200 Hz


def written_message(k, u):
    """Message k that tests/ros2_bag.rs wrote (its `written_messages`): the corrected rate as
    angular_velocity, orientation and linear acceleration not provided (element 0 of their
    covariance -1, as the message definition asks)."""
    stamp = WRITTEN_T0_NS + k * WRITTEN_STEP_NS
    gyro = [0.5 * (next(u) - 0.5) for _ in range(3)]
    var = [(1.0 + a) * 1e-6 for a in range(3)]
    return {
        "sec": stamp // 1_000_000_000,
        "nanosec": stamp % 1_000_000_000,
        "frame_id": "imu_link",
        "orientation": [0.0, 0.0, 0.0, 1.0],
        "orientation_covariance": [-1.0] + [0.0] * 8,
        "angular_velocity": gyro,
        "angular_velocity_covariance": [var[0], 0, 0, 0, var[1], 0, 0, 0, var[2]],
        "linear_acceleration": [0.0, 0.0, 0.0],
        "linear_acceleration_covariance": [-1.0] + [0.0] * 8,
    }, stamp


def as_dict(msg):
    h = msg.header
    return {
        "sec": h.stamp.sec,
        "nanosec": h.stamp.nanosec,
        "frame_id": h.frame_id,
        "orientation": [msg.orientation.x, msg.orientation.y, msg.orientation.z,
                        msg.orientation.w],
        "orientation_covariance": [float(v) for v in msg.orientation_covariance],
        "angular_velocity": [msg.angular_velocity.x, msg.angular_velocity.y,
                             msg.angular_velocity.z],
        "angular_velocity_covariance": [float(v) for v in msg.angular_velocity_covariance],
        "linear_acceleration": [msg.linear_acceleration.x, msg.linear_acceleration.y,
                                msg.linear_acceleration.z],
        "linear_acceleration_covariance": [float(v) for v in
                                           msg.linear_acceleration_covariance],
    }


def same(a, b):
    """Equal bit for bit (floats compared by their bytes, so -0.0 != 0.0)."""
    if isinstance(a, list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    if isinstance(a, float) or isinstance(b, float):
        return np.float64(a).tobytes() == np.float64(b).tobytes()
    return a == b


def check(path):
    u = splitmix64(WRITTEN_SEED)
    topics = {}
    sums = [0.0, 0.0, 0.0]
    count = 0
    first = last = None
    with Reader(path) as reader:
        for c in reader.connections:
            topics[c.topic] = {
                "type": c.msgtype,
                "message_encoding": c.ext.serialization_format,
                "offered_qos_profiles": [q._asdict() | {
                    k: getattr(q, k).name.lower()
                    for k in ("history", "reliability", "durability", "liveliness")
                } for q in c.ext.offered_qos_profiles],
                "definition_format": c.msgdef.format.name,
                "definition": c.msgdef.data,
                "messages": c.msgcount,
            }
        for c, log_time, data in reader.messages():
            assert c.msgtype == IMU, c.msgtype
            got = as_dict(STORE.deserialize_cdr(data, IMU))
            want, stamp = written_message(count, u)
            assert same(got, want), (count, got, want)
            assert log_time == stamp, (count, log_time, stamp)
            for a in range(3):
                sums[a] += got["angular_velocity"][a]
            first = first or got
            last = got
            count += 1
    assert count == WRITTEN_COUNT, count
    for t in topics.values():
        for q in t["offered_qos_profiles"]:
            for k in ("deadline", "lifespan", "liveliness_lease_duration"):
                q[k] = list(q[k])
    json.dump(
        {
            "reader": f"rosbags {VERSION}",
            "rihs01": STORE.hash_rihs01(IMU),
            "topics": topics,
            "count": count,
            "first": first,
            "last": last,
            "angular_velocity_sums": [repr(s) for s in sums],
            "every_message_as_written": True,
        },
        sys.stdout,
        indent=1,
        sort_keys=True,
    )
    sys.stdout.write("\n")


def input_accel(path):
    """The input bag's linear_acceleration by stamp: (values, provided)."""
    by_stamp = {}
    with Reader(path) as reader:
        for c, _log_time, data in reader.messages():
            if c.msgtype != IMU:
                continue
            m = as_dict(STORE.deserialize_cdr(data, IMU))
            provided = m["linear_acceleration_covariance"][0] != -1.0
            by_stamp[(m["sec"], m["nanosec"])] = (m["linear_acceleration"], provided)
    return by_stamp


def recorded(path, input_path):
    topics = {}
    digests = {}
    last_stamp = {}
    inputs = input_accel(input_path)
    with Reader(path) as reader:
        for c in reader.connections:
            topics[c.topic] = {
                "type": c.msgtype,
                "message_encoding": c.ext.serialization_format,
                "definition_format": c.msgdef.format.name,
                "messages": c.msgcount,
                "frame_ids": [],
            }
            digests[c.topic] = hashlib.sha256()
        for c, _log_time, data in reader.messages():
            assert c.msgtype == IMU, c.msgtype
            m = as_dict(STORE.deserialize_cdr(data, IMU))
            t = topics[c.topic]
            if m["frame_id"] not in t["frame_ids"]:
                t["frame_ids"].append(m["frame_id"])
            assert m["orientation_covariance"][0] == -1.0, m
            cov = m["angular_velocity_covariance"]
            assert all(np.isfinite(cov)), m
            assert all(cov[i] == 0.0 for i in range(9) if i % 4 != 0), m
            stamp = (m["sec"], m["nanosec"])
            # The accelerometer as the input gave it, bit for bit, or not provided where the
            # input did not provide it.
            acc, provided = inputs[stamp]
            acc_cov = m["linear_acceleration_covariance"]
            if provided:
                assert same(m["linear_acceleration"], acc), (stamp, m, acc)
                assert all(np.isfinite(acc_cov)) and acc_cov[0] != -1.0, m
                assert all(acc_cov[i] >= 0.0 for i in (0, 4, 8)), m
                t["accel_provided"] = t.get("accel_provided", 0) + 1
            else:
                assert acc_cov[0] == -1.0, (stamp, m)
                t["accel_not_provided"] = t.get("accel_not_provided", 0) + 1
            assert stamp > last_stamp.get(c.topic, (-(2**31), 0)), (c.topic, stamp)
            last_stamp[c.topic] = stamp
            t.setdefault("first", list(stamp))
            t["last"] = list(stamp)
            t["count"] = t.get("count", 0) + 1
            digests[c.topic].update(struct.pack("<iI", *stamp))
            digests[c.topic].update(struct.pack("<3d", *m["angular_velocity"]))
            digests[c.topic].update(struct.pack("<9d", *cov))
            digests[c.topic].update(struct.pack("<3d", *m["linear_acceleration"]))
            digests[c.topic].update(struct.pack("<9d", *acc_cov))
    for topic, d in digests.items():
        topics[topic]["sha256"] = d.hexdigest()
    json.dump(
        {
            "reader": f"rosbags {VERSION}",
            "input": os.path.basename(input_path),
            "topics": topics,
            "every_message_checked": True,
        },
        sys.stdout,
        indent=1,
        sort_keys=True,
    )
    sys.stdout.write("\n")


# --- accel: a bag whose accelerometer varies, with a stretch not provided ---------------

ACCEL_COUNT = 600  # 6 s at 100 Hz
ACCEL_SEED = 49  # issue 49
ACCEL_MISSING = range(300, 310)  # covariance element 0 = -1: not provided


def accel_message(k, u):
    """Message k of accel.mcap's /imu/data; u yields 6 splitmix doubles per message."""
    types = STORE.types
    stamp = T0_NS + k * STEP_NS
    gyro = [b + 0.02 * (next(u) - 0.5) for b in (0.011, -0.007, 0.003)]
    acc = [0.3 * (next(u) - 0.5), -0.2 + 0.3 * (next(u) - 0.5), 9.80665 + 0.05 * (next(u) - 0.5)]
    provided = k not in ACCEL_MISSING
    return types[IMU](
        header=types["std_msgs/msg/Header"](
            stamp=types["builtin_interfaces/msg/Time"](
                sec=stamp // 1_000_000_000, nanosec=stamp % 1_000_000_000
            ),
            frame_id="imu_link",
        ),
        orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=diag(-1.0, 0.0, 0.0),
        angular_velocity=types["geometry_msgs/msg/Vector3"](x=gyro[0], y=gyro[1], z=gyro[2]),
        angular_velocity_covariance=diag(1e-6, 2e-6, 3e-6),
        linear_acceleration=types["geometry_msgs/msg/Vector3"](x=acc[0], y=acc[1], z=acc[2]),
        linear_acceleration_covariance=diag(1e-4, 2e-4, 3e-4) if provided else diag(-1.0, 0.0, 0.0),
    ), stamp, acc, provided


def gen_accel():
    tmp = tempfile.mkdtemp()
    rows = []
    try:
        bag = os.path.join(tmp, "accel")
        writer = Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP)
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        with writer:
            imu = writer.add_connection(
                "/imu/data", IMU, typestore=STORE, offered_qos_profiles=[RELIABLE_KEEP_LAST_10]
            )
            u = splitmix64(ACCEL_SEED)
            for k in range(ACCEL_COUNT):
                msg, stamp, acc, provided = accel_message(k, u)
                writer.write(imu, stamp + 1_000_000, bytes(STORE.serialize_cdr(msg, IMU)))
                rows.append([stamp] + [repr(v) for v in acc] + [int(provided)])
        shutil.copyfile(os.path.join(bag, "accel.mcap"), os.path.join(HERE, "accel.mcap"))
    finally:
        shutil.rmtree(tmp)
    with open(os.path.join(HERE, "accel.csv"), "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["stamp_ns", "ax", "ay", "az", "provided"])
        w.writerows(rows)
    print("wrote accel.mcap, accel.csv in", os.path.normpath(HERE), len(rows), "messages")


# --- odom: a bag whose odometry gives the vehicle's stops ------------------------------

ODOM = "nav_msgs/msg/Odometry"
ODOM_COUNT = 1500  # Imu messages: 15 s at 100 Hz
ODOM_EVERY = 5  # an Odometry message every 5th Imu stamp (20 Hz)
ODOM_LAG_NS = 3_000_000


def odom_message(stamp, moving, jitter):
    types = STORE.types
    vec = types["geometry_msgs/msg/Vector3"]
    linear = vec(x=1.5, y=0.0, z=0.0) if moving else vec(x=0.0, y=jitter, z=0.0)
    cov = np.arange(36, dtype=np.float64) * 1e-3
    return types[ODOM](
        header=types["std_msgs/msg/Header"](
            stamp=types["builtin_interfaces/msg/Time"](
                sec=stamp // 1_000_000_000, nanosec=stamp % 1_000_000_000
            ),
            frame_id="odom",
        ),
        child_frame_id="base_link",
        pose=types["geometry_msgs/msg/PoseWithCovariance"](
            pose=types["geometry_msgs/msg/Pose"](
                position=types["geometry_msgs/msg/Point"](x=12.5, y=-3.25, z=0.0),
                orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.6, w=0.8),
            ),
            covariance=cov,
        ),
        twist=types["geometry_msgs/msg/TwistWithCovariance"](
            twist=types["geometry_msgs/msg/Twist"](linear=linear, angular=vec(x=0.0, y=0.0, z=0.25)),
            covariance=cov,
        ),
    )


def gen_odom():
    tmp = tempfile.mkdtemp()
    bias = np.radians([0.4, -0.2, 0.1])
    rows = []
    try:
        bag = os.path.join(tmp, "odom")
        writer = Writer(bag, version=9, storage_plugin=StoragePlugin.MCAP)
        writer.set_compression(CompressionMode.STORAGE, CompressionFormat.ZSTD)
        with writer:
            imu = writer.add_connection(
                "/imu/data", IMU, typestore=STORE, offered_qos_profiles=[RELIABLE_KEEP_LAST_10]
            )
            odom = writer.add_connection(
                "/odom", ODOM, typestore=STORE, offered_qos_profiles=[RELIABLE_KEEP_LAST_10]
            )
            u = splitmix64(SEED + 10)
            types = STORE.types
            for k in range(ODOM_COUNT):
                stamp = T0_NS + k * STEP_NS
                w = [b + np.radians(0.02) * (next(u) - 0.5) for b in bias]
                msg = types[IMU](
                    header=types["std_msgs/msg/Header"](
                        stamp=types["builtin_interfaces/msg/Time"](
                            sec=stamp // 1_000_000_000, nanosec=stamp % 1_000_000_000
                        ),
                        frame_id="imu_link",
                    ),
                    orientation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                    orientation_covariance=diag(-1.0, 0.0, 0.0),
                    angular_velocity=types["geometry_msgs/msg/Vector3"](x=w[0], y=w[1], z=w[2]),
                    angular_velocity_covariance=diag(1e-6, 1e-6, 1e-6),
                    linear_acceleration=types["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=9.8),
                    linear_acceleration_covariance=diag(1e-4, 1e-4, 1e-4),
                )
                writer.write(imu, stamp + 1_000_000, bytes(STORE.serialize_cdr(msg, IMU)))
                third = k * 3 // ODOM_COUNT
                if k % ODOM_EVERY == 0 and third < 2:
                    o_stamp = stamp + ODOM_LAG_NS
                    jitter = 0.004 * (next(u) - 0.5)
                    o = odom_message(o_stamp, third == 0, jitter)
                    writer.write(odom, o_stamp + 500_000, bytes(STORE.serialize_cdr(o, ODOM)))
                    t = o.twist.twist.linear
                    rows.append([o_stamp, repr(float(np.sqrt(t.x * t.x + t.y * t.y + t.z * t.z)))])
        shutil.copyfile(os.path.join(bag, "odom.mcap"), os.path.join(HERE, "odom.mcap"))
    finally:
        shutil.rmtree(tmp)
    with open(os.path.join(HERE, "odom.csv"), "w", newline="") as f:
        w = csv.writer(f, lineterminator="\n")
        w.writerow(["stamp_ns", "speed"])
        w.writerows(rows)
    print("wrote odom.mcap, odom.csv in", os.path.normpath(HERE), len(rows), "odometry messages")


if __name__ == "__main__":
    if len(sys.argv) >= 2 and sys.argv[1] == "odom":
        gen_odom()
    elif len(sys.argv) >= 2 and sys.argv[1] == "check":
        check(sys.argv[2])
    elif len(sys.argv) >= 2 and sys.argv[1] == "recorded":
        recorded(sys.argv[2], sys.argv[3] if len(sys.argv) > 3 else os.path.join(HERE, "accel.mcap"))
    elif len(sys.argv) >= 2 and sys.argv[1] == "accel":
        gen_accel()
    else:
        gen()
