"""A stand-in navigator node: subscribes the daemon's corrected rate (sensor_msgs/msg/Imu on
/imu/corrected) and integrates heading about z, with its variance grown by each message's
angular_velocity_covariance (the rate's variance: the daemon's rate noise plus the bias filter's
own uncertainty) times dt^2, as a navigator's filter propagates a rate measurement.

    python3 examples/ros2/navigator.py --count 8000

Every second it prints the heading; at the end one JSON line: messages, heading (rad), its
1 sigma (rad), and whether every stamp rose.
"""

import argparse
import json
import math
import time

import rclpy
from rclpy.node import Node
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import Imu


class Navigator(Node):
    def __init__(self) -> None:
        super().__init__("navigator")
        qos = QoSProfile(depth=1000, reliability=ReliabilityPolicy.RELIABLE,
                         history=HistoryPolicy.KEEP_LAST)
        self.create_subscription(Imu, "/imu/corrected", self.on_imu, qos)
        self.count = 0
        self.heading = 0.0
        self.variance = 0.0
        self.last = None
        self.in_order = True

    def on_imu(self, m: Imu) -> None:
        t = m.header.stamp.sec + m.header.stamp.nanosec * 1e-9
        if self.last is not None:
            dt = t - self.last
            if dt <= 0:
                self.in_order = False
            else:
                self.heading += m.angular_velocity.z * dt
                self.variance += max(m.angular_velocity_covariance[8], 0.0) * dt * dt
        self.last = t
        self.count += 1


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--count", type=int, default=0, help="stop after this many (0: Ctrl-C)")
    ap.add_argument("--timeout", type=float, default=60.0, help="seconds at most")
    args = ap.parse_args()
    rclpy.init()
    nav = Navigator()
    print(json.dumps({"ready": True}), flush=True)
    end = time.monotonic() + args.timeout
    next_line = time.monotonic() + 1.0
    try:
        while time.monotonic() < end and (args.count == 0 or nav.count < args.count):
            rclpy.spin_once(nav, timeout_sec=0.05)
            if time.monotonic() >= next_line:
                print(f"navigator: {nav.count} messages, heading {math.degrees(nav.heading):+.3f} deg",
                      flush=True)
                next_line += 1.0
    except KeyboardInterrupt:
        pass
    print(json.dumps({"messages": nav.count, "heading_rad": nav.heading,
                      "sigma_rad": math.sqrt(nav.variance), "in_order": nav.in_order}), flush=True)
    nav.destroy_node()
    rclpy.shutdown()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
