"""A stand-in IMU driver node: publishes a simulated gyro as sensor_msgs/msg/Imu on
/imu/data_raw (rad/s, REP 103) and the vehicle's motion as nav_msgs/msg/Odometry on /odom, as a
real driver and a wheel-odometry node would. The vehicle stands, turns at --turn-rate about z
for --turn-s seconds in the middle of the run, and stands again; the gyro adds a constant bias
and white noise (seeded). Replace it with your driver.

    python3 examples/ros2/driver.py --duration 8 --rate 1000

At exit it prints one JSON line: what it sent, the true heading change and the raw gyro's
integral, so a navigator's heading can be judged against both.
"""

import argparse
import json
import random
import time

import rclpy
from nav_msgs.msg import Odometry
from rclpy.node import Node
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import Imu

BIAS = (0.003, -0.002, 0.004)  # rad/s
NOISE = 0.02  # rad/s per sample, 1 sigma


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rate", type=float, default=1000.0, help="samples per second")
    ap.add_argument("--duration", type=float, default=8.0, help="seconds")
    ap.add_argument("--turn-rate", type=float, default=0.2, help="rad/s about z while turning")
    ap.add_argument("--turn-s", type=float, default=1.0, help="seconds of turning")
    ap.add_argument("--wait", type=float, default=20.0, help="seconds to wait for a subscriber")
    args = ap.parse_args()

    rclpy.init()
    node = Node("imu_driver")
    # Drivers publish with the sensor-data QoS (best effort); the daemon accepts it.
    imu_pub = node.create_publisher(Imu, "/imu/data_raw", qos_profile_sensor_data)
    odom_pub = node.create_publisher(Odometry, "/odom", 10)
    end = time.monotonic() + args.wait
    while imu_pub.get_subscription_count() == 0 and time.monotonic() < end:
        time.sleep(0.01)
    time.sleep(0.5)  # the subscriber's side of discovery

    rng = random.Random(7)
    n = int(args.duration * args.rate)
    dt = 1.0 / args.rate
    turn_from = int((args.duration - args.turn_s) / 2 * args.rate)
    turn_to = turn_from + int(args.turn_s * args.rate)
    t0 = time.time_ns()
    start = time.monotonic()
    truth = raw = 0.0
    for k in range(n):
        turning = turn_from <= k < turn_to
        wz = args.turn_rate if turning else 0.0
        m = Imu()
        stamp = t0 + int(k * 1e9 / args.rate)
        m.header.stamp.sec, m.header.stamp.nanosec = divmod(stamp, 1_000_000_000)
        m.header.frame_id = "imu_link"
        m.orientation_covariance[0] = -1.0
        m.linear_acceleration_covariance[0] = -1.0
        m.angular_velocity.x = BIAS[0] + rng.gauss(0.0, NOISE)
        m.angular_velocity.y = BIAS[1] + rng.gauss(0.0, NOISE)
        m.angular_velocity.z = wz + BIAS[2] + rng.gauss(0.0, NOISE)
        for a in range(3):
            m.angular_velocity_covariance[4 * a] = NOISE**2
        imu_pub.publish(m)
        truth += wz * dt
        raw += m.angular_velocity.z * dt
        if k % 20 == 0:
            o = Odometry()
            o.header = m.header
            o.twist.twist.linear.x = 1.0 if turning else 0.0
            o.twist.twist.angular.z = wz
            odom_pub.publish(o)
        # Paced on the clock, not on sleeps: a late wake-up does not slow the stream.
        ahead = start + (k + 1) * dt - time.monotonic()
        if ahead > 0:
            time.sleep(ahead)
    print(json.dumps({"sent": n, "truth_rad": truth, "raw_rad": raw}), flush=True)
    node.destroy_node()
    rclpy.shutdown()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
