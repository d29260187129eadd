"""A real ROS 2 (rclpy) peer for tests/ros2_live.rs: `listen` prints each sensor_msgs/msg/Imu it
receives on TOPIC as a JSON line, then the graph it sees; `talk` waits for a subscriber on TOPIC
and publishes COUNT messages whose fields follow from their index (as the test expects); `drive`
does the same with a gyro at rest and publishes nav_msgs/msg/Odometry on /odom every 10th
message, the vehicle moving at 1 m/s for the first half and standing for the second;
`wrongtype` publishes COUNT geometry_msgs/msg/Vector3Stamped on TOPIC, one every 10 ms. With
PEER_NAN_AT=i,j,... `talk` sends NaN rates in those messages; with
PEER_DURABILITY=transient_local `listen` asks for that durability. With
PEER_STAMPS=i=what,... `talk` sends wild stamps in those messages: `max` the farthest a ROS 2
stamp holds (2038-01-19), `zero` 0 ("not set"), `back` one second before the message's own.
`twin` publishes COUNT messages from each of two publishers on TOPIC, alternating (two drivers
on one topic): the second's rates are the first's negated. With PEER_ACCEL=1 `talk` and `drive`
send an accelerometer reading too (`accel(i)`: every message's own doubles, not round ones)
with a covariance for each field (orientation still not provided). `bias` prints each
geometry_msgs/msg/Vector3Stamped it receives on TOPIC as a JSON line, `diagnostics` each
diagnostic_msgs/msg/DiagnosticArray, until COUNT came. PEER_NODE names the node. For benches/ros2.rs: `pace`
publishes COUNT messages at PEER_RATE Hz (default 1000) stamped with the system clock just
before each publish (`pace-odom`: and a moving, straight nav_msgs/msg/Odometry on /odom at 50
Hz with a yaw-rate covariance); `latency` receives COUNT and prints, as one JSON line, how many came, in
order, and the percentiles of receipt minus stamp (us). `mag` publishes COUNT Imu messages
of a level gyro at rest (gravity on z, with a covariance) and, before every 10th, a
sensor_msgs/msg/MagneticField on /imu/mag with the same stamp: the field (tesla) of 20 uT north
and 40 uT down seen by a body turned MAG_YAW_DEG (default 30) anticlockwise from east (ENU),
until message PEER_MAG_UNTIL (default COUNT), then no more (the magnetometer stops); with
PEER_MAG_NAN_AT=i,... the readings before those messages are NaN. `turn` is a vehicle that
never stops: COUNT Imu messages at 1 kHz stamped with the system clock, a gyro with the bias
TURN_BIAS (rad/s) whose z turns with the vehicle (up is +z: 1 s each of 0, 20, 0, -15, 10
deg/s), and a nav_msgs/msg/Odometry at 50 Hz (2 m/s, `angular.z` the true mean yaw rate over
its 20 ms, its covariance's yaw variance set) stamped with the end of its period and
published 30 ms later, as a wheel odometry's latency.

Runs inside the test's private network namespace only (DDS never leaves it).
Versions: requirements-ros2.txt beside this file.
"""

import json
import math
import os
import sys
import time

import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Vector3Stamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import Imu, MagneticField


ACCEL_COVARIANCE = [1e-4, 1e-6, 0.0, 1e-6, 2e-4, 0.0, 0.0, 0.0, 3e-4]

# The `turn` mode's gyro bias, rad/s (tests/ros2_live.rs checks against it).
TURN_BIAS = [0.002, -0.001, 0.004]


def accel(i: int) -> list:
    """Message `i`'s specific force, m/s^2: gravity on z and a wobble whose doubles are odd.
    Only +, *, / and %: IEEE rounds them alike everywhere, so the test computes the same bits."""
    return [
        (i * 7919 % 1009) / 1009.0 * 0.3 - 0.15,
        -0.2 + (i * 104729 % 997) / 997.0 * 0.1,
        9.80665 + i / 3.0e4,
    ]


def message(i: int, still: bool = False) -> Imu:
    """Message `i`; `still`: a gyro at rest (a bias of a few mrad/s and a little noise)."""
    m = Imu()
    m.header.stamp.sec = 1_700_000_000 + i // 1000
    m.header.stamp.nanosec = (i % 1000) * 1_000_000
    m.header.frame_id = "peer_imu"
    m.orientation_covariance[0] = -1.0
    m.angular_velocity.x = 0.001 * i
    m.angular_velocity.y = -0.002 * i
    m.angular_velocity.z = 0.5
    if still:
        m.angular_velocity.x = 0.002 + 1e-4 * math.sin(0.7 * i)
        m.angular_velocity.y = -0.001 + 1e-4 * math.sin(1.3 * i)
        m.angular_velocity.z = 0.0005 + 1e-4 * math.sin(2.9 * i)
    m.angular_velocity_covariance = [1e-6 * (k + 1) for k in range(9)]
    m.linear_acceleration_covariance[0] = -1.0
    if os.environ.get("PEER_ACCEL") == "1":
        m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z = accel(i)
        m.linear_acceleration_covariance = ACCEL_COVARIANCE
    return m


def as_dict(m: Imu) -> dict:
    return {
        "stamp": [m.header.stamp.sec, m.header.stamp.nanosec],
        "frame_id": m.header.frame_id,
        "orientation": [m.orientation.x, m.orientation.y, m.orientation.z, m.orientation.w],
        "orientation_covariance": list(m.orientation_covariance),
        "angular_velocity": [m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z],
        "angular_velocity_covariance": list(m.angular_velocity_covariance),
        "linear_acceleration": [
            m.linear_acceleration.x, m.linear_acceleration.y, m.linear_acceleration.z
        ],
        "linear_acceleration_covariance": list(m.linear_acceleration_covariance),
    }


def bias_dict(m: Vector3Stamped) -> dict:
    return {
        "stamp": [m.header.stamp.sec, m.header.stamp.nanosec],
        "frame_id": m.header.frame_id,
        "vector": [m.vector.x, m.vector.y, m.vector.z],
    }


def diagnostics_dict(m: DiagnosticArray) -> dict:
    return {
        "stamp": [m.header.stamp.sec, m.header.stamp.nanosec],
        "status": [
            {
                "level": int.from_bytes(s.level, "little") if isinstance(s.level, bytes) else s.level,
                "name": s.name,
                "message": s.message,
                "hardware_id": s.hardware_id,
                "values": {kv.key: kv.value for kv in s.values},
            }
            for s in m.status
        ],
    }


def main() -> int:
    mode, topic, count, timeout = sys.argv[1], sys.argv[2], int(sys.argv[3]), float(sys.argv[4])
    rclpy.init()
    node = Node(os.environ.get("PEER_NODE", "driftless_test_peer"))
    end = time.monotonic() + timeout
    if mode == "listen":
        reliable = QoSProfile(depth=max(count, 10), reliability=ReliabilityPolicy.RELIABLE,
                              history=HistoryPolicy.KEEP_LAST)
        if os.environ.get("PEER_DURABILITY") == "transient_local":
            reliable.durability = DurabilityPolicy.TRANSIENT_LOCAL
        got = []
        node.create_subscription(Imu, topic, lambda m: got.append(as_dict(m)), reliable)
        print(json.dumps({"ready": True}), flush=True)
        while len(got) < count and time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.05)
        for g in got:
            print(json.dumps(g), flush=True)
        graph = {
            "topics": node.get_topic_names_and_types(),
            "nodes": [n for n, _ in node.get_node_names_and_namespaces()],
            "publishers": [(p.node_name, p.topic_type) for p in node.get_publishers_info_by_topic(topic)],
        }
        print(json.dumps({"graph": graph}), flush=True)
    elif mode in ("bias", "diagnostics"):
        reliable = QoSProfile(depth=max(count, 10), reliability=ReliabilityPolicy.RELIABLE,
                              history=HistoryPolicy.KEEP_LAST)
        got = []
        ty, as_json = (Vector3Stamped, bias_dict) if mode == "bias" else (
            DiagnosticArray, diagnostics_dict)
        node.create_subscription(ty, topic, lambda m: got.append(as_json(m)), reliable)
        print(json.dumps({"ready": True}), flush=True)
        while len(got) < count and time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.05)
        for g in got:
            print(json.dumps(g), flush=True)
    elif mode == "latency":
        reliable = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                              history=HistoryPolicy.KEEP_LAST)
        lat, stamps = [], []

        def on_imu(m):
            now = time.time_ns()
            stamp = m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec
            lat.append((now - stamp) / 1e3)
            stamps.append(stamp)

        node.create_subscription(Imu, topic, on_imu, reliable)
        print(json.dumps({"ready": True}), flush=True)
        while len(lat) < count and time.monotonic() < end:
            rclpy.spin_once(node, timeout_sec=0.05)
        ordered = sorted(lat)

        def pct(q):
            return ordered[min(len(ordered) - 1, int(q * len(ordered)))] if ordered else None

        print(json.dumps({
            "count": len(lat),
            "in_order": all(b > a for a, b in zip(stamps, stamps[1:])),
            "p50_us": pct(0.5), "p99_us": pct(0.99), "p999_us": pct(0.999),
            "max_us": ordered[-1] if ordered else None,
        }), flush=True)
    elif mode in ("pace", "pace-odom"):
        rate = float(os.environ.get("PEER_RATE", "1000"))
        pub = node.create_publisher(Imu, topic, 10)
        odom = node.create_publisher(Odometry, "/odom", 10) if mode == "pace-odom" else None
        while time.monotonic() < end and (
            pub.get_subscription_count() == 0
            or (odom is not None and odom.get_subscription_count() == 0)
        ):
            time.sleep(0.01)
        time.sleep(0.5)
        start = time.monotonic()
        m = message(0, still=True)
        o = Odometry()
        o.twist.twist.linear.x = 2.0
        o.twist.covariance[35] = math.radians(0.1) ** 2
        for i in range(count):
            stamp = time.time_ns()
            m.header.stamp.sec, m.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
            pub.publish(m)
            if odom is not None and i % round(rate / 50) == 0:
                o.header.stamp = m.header.stamp
                odom.publish(o)
            ahead = start + (i + 1) / rate - time.monotonic()
            if ahead > 0:
                time.sleep(ahead)
        time.sleep(0.5)
        print(json.dumps({"sent": count}), flush=True)
    elif mode == "mag":
        yaw = math.radians(float(os.environ.get("MAG_YAW_DEG", "30")))
        until = int(os.environ.get("PEER_MAG_UNTIL", str(count)))
        mag_nan_at = {int(k) for k in os.environ.get("PEER_MAG_NAN_AT", "").split(",") if k}
        pub = node.create_publisher(Imu, topic, 10)
        mag_pub = node.create_publisher(MagneticField, "/imu/mag", 10)
        while time.monotonic() < end and (
            pub.get_subscription_count() == 0 or mag_pub.get_subscription_count() == 0
        ):
            time.sleep(0.01)
        time.sleep(0.5)
        for i in range(count):
            m = message(i, still=True)
            m.linear_acceleration.x, m.linear_acceleration.y = 0.0, 0.0
            m.linear_acceleration.z = 9.80665
            m.linear_acceleration_covariance = ACCEL_COVARIANCE
            if i % 10 == 0 and i < until:
                f = MagneticField()
                f.header = m.header
                # The body's view of the earth's field: Rz(-yaw) (0, 20, -40) uT.
                f.magnetic_field.x = 20e-6 * math.sin(yaw)
                f.magnetic_field.y = 20e-6 * math.cos(yaw)
                f.magnetic_field.z = -40e-6
                f.magnetic_field_covariance = [1e-14, 0.0, 0.0, 0.0, 1e-14, 0.0, 0.0, 0.0, 1e-14]
                if i in mag_nan_at:
                    f.magnetic_field.x = float("nan")
                mag_pub.publish(f)
            pub.publish(m)
            time.sleep(0.001)
        time.sleep(0.5)
        print(json.dumps({"sent": count}), flush=True)
    elif mode == "turn":
        bias = TURN_BIAS
        pub = node.create_publisher(Imu, topic, 10)
        odom = node.create_publisher(Odometry, "/odom", 10)
        while time.monotonic() < end and (
            pub.get_subscription_count() == 0 or odom.get_subscription_count() == 0
        ):
            time.sleep(0.01)
        time.sleep(0.5)
        start = time.monotonic()
        pending, turned = [], 0.0
        for i in range(count):
            stamp = time.time_ns()
            w = math.radians([0.0, 20.0, 0.0, -15.0, 10.0][(i // 1000) % 5])
            m = Imu()
            m.header.stamp.sec, m.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
            m.header.frame_id = "peer_imu"
            m.orientation_covariance[0] = -1.0
            m.angular_velocity.x = bias[0] + 1e-3 * math.sin(0.7 * i)
            m.angular_velocity.y = bias[1] + 1e-3 * math.sin(1.3 * i)
            m.angular_velocity.z = bias[2] + w + 1e-3 * math.sin(2.9 * i)
            m.linear_acceleration_covariance[0] = -1.0
            pub.publish(m)
            turned += w
            if (i + 1) % 20 == 0:
                o = Odometry()
                o.header.stamp = m.header.stamp
                o.twist.twist.linear.x = 2.0
                o.twist.twist.angular.z = turned / 20
                o.twist.covariance[35] = math.radians(0.1) ** 2
                pending.append((i + 30, o))
                turned = 0.0
            while pending and pending[0][0] <= i:
                odom.publish(pending.pop(0)[1])
            ahead = start + (i + 1) / 1000.0 - time.monotonic()
            if ahead > 0:
                time.sleep(ahead)
        time.sleep(0.5)
        print(json.dumps({"sent": count}), flush=True)
    elif mode == "wrongtype":
        pub = node.create_publisher(Vector3Stamped, topic, 10)
        for _ in range(count):
            pub.publish(Vector3Stamped())
            time.sleep(0.01)
    elif mode == "twin":
        pubs = [node.create_publisher(Imu, topic, 10) for _ in range(2)]
        while time.monotonic() < end and any(p.get_subscription_count() == 0 for p in pubs):
            time.sleep(0.01)
        time.sleep(0.5)
        for i in range(count):
            for k, pub in enumerate(pubs):
                m = message(i)
                if k == 1:
                    m.angular_velocity.x *= -1.0
                    m.angular_velocity.y *= -1.0
                    m.angular_velocity.z *= -1.0
                pub.publish(m)
            time.sleep(0.001)
        time.sleep(0.5)
        print(json.dumps({"sent": count}), flush=True)
    else:
        nan_at = {int(k) for k in os.environ.get("PEER_NAN_AT", "").split(",") if k}
        stamps = dict(kv.split("=") for kv in os.environ.get("PEER_STAMPS", "").split(",") if kv)
        pub = node.create_publisher(Imu, topic, 10)
        odom = node.create_publisher(Odometry, "/odom", 10) if mode == "drive" else None
        while time.monotonic() < end and (
            pub.get_subscription_count() == 0
            or (odom is not None and odom.get_subscription_count() == 0)
        ):
            time.sleep(0.01)
        # Matched here is not yet matched there: give the other side's discovery time.
        time.sleep(0.5)
        for i in range(count):
            if odom is not None and i % 10 == 0:
                o = Odometry()
                o.header.stamp = message(i).header.stamp
                o.twist.twist.linear.x = 1.0 if i < count // 2 else 0.0
                odom.publish(o)
            m = message(i, still=odom is not None)
            if i in nan_at:
                m.angular_velocity.x = float("nan")
            wild = stamps.get(str(i))
            if wild == "max":
                m.header.stamp.sec, m.header.stamp.nanosec = 2**31 - 1, 0
            elif wild == "zero":
                m.header.stamp.sec, m.header.stamp.nanosec = 0, 0
            elif wild == "back":
                m.header.stamp.sec -= 1
            pub.publish(m)
            time.sleep(0.001)
        time.sleep(0.5)
        print(json.dumps({"sent": count}), flush=True)
    node.destroy_node()
    rclpy.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
