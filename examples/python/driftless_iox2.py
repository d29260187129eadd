"""What driver.py and subscriber.py share: driftless's wire types as ctypes structures, the
iceoryx2 node set-up the daemon uses (prefix, root, QoS), clean-up, and the driver's
deterministic sample pattern.

Needs iceoryx2's own Python bindings at the version of the Rust crate (requirements.txt:
iceoryx2==0.10.0). The layouts are docs/wire-types.md's tables ("Layouts"); the type
names are those of `#[type_name(...)]` in the Rust sources, so both sides get the same iceoryx2
type id (name, size and alignment must all match, or opening fails with IncompatibleTypes).
"""

import ctypes
import math
import os
import re
import signal
import stat
import sys

import iceoryx2 as iox2

# iceoryx2's version must be the Rust crate's: services of another version are invisible or
# refused. Fail early with a clear message rather than with a confusing lookup error.
_NEED = "0.10.0"


def _check_version() -> None:
    try:
        from importlib.metadata import version

        have = version("iceoryx2")
    except Exception:  # noqa: BLE001 (metadata missing: nothing to say)
        return
    if have != _NEED:
        sys.exit(f"iceoryx2 {have} is installed; driftless speaks iceoryx2 {_NEED} "
                 f"(pip install iceoryx2=={_NEED})")


_check_version()

DEFAULT_PREFIX = "driftless_"  # transport::DEFAULT_PREFIX
PREFIX_ENV = "DRIFTLESS_IOX2_PREFIX"  # transport::PREFIX_ENV
DEFAULT_ROOT = "/tmp/iceoryx2"  # transport::DEFAULT_ROOT
ROOT_ENV = "DRIFTLESS_IOX2_ROOT"  # transport::ROOT_ENV

# The daemon's QoS (transport::Qos::default(), the pipeline's [iceoryx2] buffer_size and
# max_subscribers): a service created here must be one the daemon accepts.
BUFFER_SIZE = 256
MAX_SUBSCRIBERS = 8

# Output flags (wire::FLAG_*).
FLAG_WARMING_UP = 1
FLAG_INPUT_INVALID = 1 << 1
FLAG_GAP_BEFORE = 1 << 2
FLAG_TIME_BACKWARDS = 1 << 3
FLAG_FLUSHED = 1 << 4
FLAG_OUTPUT_REPAIRED = 1 << 5
FLAG_STAMP_FAULT = 1 << 11
# Flags that say a delivered sample is not what the driver sent.
FLAGS_BAD = (FLAG_INPUT_INVALID | FLAG_GAP_BEFORE | FLAG_TIME_BACKWARDS | FLAG_OUTPUT_REPAIRED
             | FLAG_STAMP_FAULT)

# Raw-sample flags (wire::RAW_*): the sample carries an accelerometer / magnetometer reading.
RAW_ACCEL = 1 << 4
RAW_MAG = 1 << 5
# GyroSample.sensors (wire::SENSOR_*): which readings are present, which were held.
SENSOR_ACCEL = 1
SENSOR_MAG = 1 << 1
SENSOR_ACCEL_INVALID = 1 << 2
SENSOR_MAG_INVALID = 1 << 3
# ... and the attitude stage's: an orientation is present; it coasted on the gyro (no valid
# accelerometer); the accelerometer read free fall or a shock.
SENSOR_ORIENTATION = 1 << 4
SENSOR_ORIENTATION_COASTING = 1 << 5
SENSOR_ORIENTATION_NO_GRAVITY = 1 << 6
# ... and with the magnetometer (use_mag): the heading is absolute (from north, not from where
# the stage started; orientation_std's z is then the magnetometer filter's); the field was
# rejected as disturbed at this sample (the heading rests on the gyro).
SENSOR_HEADING_ABSOLUTE = 1 << 7
SENSOR_MAG_REJECTED = 1 << 8

# GyroSample.drift_std where no stage estimates the drift's uncertainty (predict.none,
# predict.rbf, no predict stage): wire::DRIFT_STD_NOT_PROVIDED. Never NaN.
DRIFT_STD_NOT_PROVIDED = -1.0


class RawSample(ctypes.Structure):
    """`driftless::RawSample.v2`, 96 bytes: what a driver publishes for `ingest.iceoryx2`.

    Layout version 2 (wire::RAW_VERSION): version 1 (`driftless::RawSample`, 48 bytes)
    ended at `epoch`. A gyro-only driver leaves RAW_ACCEL and RAW_MAG clear."""

    _fields_ = [
        ("t_ns", ctypes.c_uint64),  # 0: sensor timestamp, ns
        ("seq", ctypes.c_uint64),  # 8: +1 per sample
        ("rate", ctypes.c_double * 3),  # 16: x, y, z in the pipeline's input_units
        ("flags", ctypes.c_uint32),  # 40: bit 0 invalid, RAW_ACCEL, RAW_MAG, ...
        ("epoch", ctypes.c_uint32),  # 44: the driver's run id (non-zero per start)
        ("accel", ctypes.c_double * 3),  # 48: specific force in the pipeline's accel_units
        ("mag", ctypes.c_double * 3),  # 72: magnetic field, tesla
    ]

    @staticmethod
    def type_name() -> str:
        """iceoryx2's type name (Rust `wire::RAW_TYPE_NAME`)."""
        return "driftless::RawSample.v2"


class GyroSample(ctypes.Structure):
    """`driftless::GyroSample.v4`, 264 bytes: every hop after the ingest, and the public output.

    Layout version 4 (wire::GYRO_VERSION): version 3 (`driftless::GyroSample.v3`, 208
    bytes) ended at `reserved`, version 2 (`driftless::GyroSample.v2`, 128 bytes) at
    `drift_std`, version 1 (`driftless::GyroSample`, 104 bytes) at `epoch`. A
    service of another version is refused by iceoryx2 with IncompatibleTypes: run the daemon
    and this subscriber from one release."""

    _fields_ = [
        ("t_ns", ctypes.c_uint64),  # 0: sensor timestamp of this sample
        ("seq", ctypes.c_uint64),  # 8: unchanged from the raw sample
        ("ingest_ns", ctypes.c_uint64),  # 16: CLOCK_MONOTONIC at the daemon's ingest
        ("rate", ctypes.c_double * 3),  # 24: corrected rate, rad/s
        ("drift", ctypes.c_double * 3),  # 48: drift estimate, rad/s
        ("denoised", ctypes.c_double * 3),  # 72: denoised rate, rad/s
        ("flags", ctypes.c_uint32),  # 96: FLAG_*
        ("epoch", ctypes.c_uint32),  # 100: the stream's run id
        ("drift_std", ctypes.c_double * 3),  # 104: 1-sigma of drift, rad/s; -1: not provided
        ("accel", ctypes.c_double * 3),  # 128: specific force, m/s^2 (with SENSOR_ACCEL)
        ("accel_std", ctypes.c_double * 3),  # 152: 1-sigma of one accel sample; -1: not provided
        ("mag", ctypes.c_double * 3),  # 176: magnetic field, tesla (with SENSOR_MAG)
        ("sensors", ctypes.c_uint32),  # 200: SENSOR_*
        ("reserved", ctypes.c_uint32),  # 204: 0
        # 208: x, y, z, w, body to earth (z up, heading relative unless SENSOR_HEADING_ABSOLUTE)
        # (with SENSOR_ORIENTATION)
        ("orientation", ctypes.c_double * 4),
        ("orientation_std", ctypes.c_double * 3),  # 240: 1-sigma about earth x, y, z, rad; -1
    ]

    @staticmethod
    def type_name() -> str:
        """iceoryx2's type name (Rust `wire::GYRO_TYPE_NAME`)."""
        return "driftless::GyroSample.v4"


# The documented layouts, checked once: a wrong field order or type fails here, not on the wire.
for _t, _size, _offsets in (
    (RawSample, 96, {"t_ns": 0, "seq": 8, "rate": 16, "flags": 40, "epoch": 44, "accel": 48,
                     "mag": 72}),
    (GyroSample, 264, {"t_ns": 0, "seq": 8, "ingest_ns": 16, "rate": 24, "drift": 48,
                       "denoised": 72, "flags": 96, "epoch": 100, "drift_std": 104,
                       "accel": 128, "accel_std": 152, "mag": 176, "sensors": 200,
                       "orientation": 208, "orientation_std": 240}),
):
    assert ctypes.sizeof(_t) == _size and ctypes.alignment(_t) == 8, _t
    assert {f: getattr(_t, f).offset for f in _offsets} == _offsets, _t
    assert sys.byteorder == "little"

# The driver's deterministic pattern, deg/s: a constant rate per axis plus a zero-mean dither
# of period 17 (so the denoiser has noise to estimate; the mean over each period is exactly the
# base). The z axis turns at 10 deg/s, so heading grows 10 deg per second of samples.
PATTERN_BASE_DEG_S = (1.5, -2.0, 10.0)
PATTERN_DITHER_DEG_S = 0.05
PATTERN_PERIOD = 17


def pattern(seq: int) -> tuple:
    """The rate driver.py sends at `seq`, deg/s per axis."""
    d = PATTERN_DITHER_DEG_S * (((seq * 7) % PATTERN_PERIOD) - 8) / 8
    return tuple(b + (d if i % 2 == 0 else -d) for i, b in enumerate(PATTERN_BASE_DEG_S))


def accel_pattern(seq: int) -> tuple:
    """The specific force driver.py sends at `seq`, m/s^2: gravity on z and a small tilt that
    changes with seq, so that a subscriber can tell each sample's reading from its neighbours'."""
    return (0.001 * (seq % 101), -0.002 * (seq % 53), -9.80665)


def roll_pitch_yaw(q) -> tuple:
    """Roll, pitch and yaw (rad; ZYX, as ROS tf2) of a body-to-earth quaternion (x, y, z, w),
    as driftless::attitude::roll_pitch_yaw."""
    x, y, z, w = q
    roll = math.atan2(2 * (w * x + y * z), 1 - 2 * (x * x + y * y))
    pitch = math.asin(max(-1.0, min(1.0, 2 * (w * y - z * x))))
    yaw = math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))
    return roll, pitch, yaw


def t_ns_of(seq: int, rate_hz: float) -> int:
    """The sensor timestamp driver.py gives sample `seq` (as raw_driver.rs does)."""
    return round(seq * 1e9 / rate_hz)


def resolve_prefix(option) -> str:
    """The option, else DRIFTLESS_IOX2_PREFIX, else driftless_ (as the daemon resolves it),
    checked as the daemon checks it (transport::check_prefix)."""
    prefix = option or os.environ.get(PREFIX_ENV) or DEFAULT_PREFIX
    if not _PREFIX.fullmatch(prefix):
        sys.exit(f"iceoryx2 prefix {prefix!r}: a prefix is letters, digits, '-' or '.', then "
                 "one '_' at the end and no other (at most 64 bytes)")
    return prefix


def resolve_root(option) -> str:
    """The option, else DRIFTLESS_IOX2_ROOT, else /tmp/iceoryx2."""
    root = option or os.environ.get(ROOT_ENV) or DEFAULT_ROOT
    if not root.startswith("/"):
        sys.exit(f"iceoryx2 root path {root!r}: must be an absolute path")
    return root


def config(prefix: str, root: str):
    """An explicit iceoryx2 config: prefix and root as the daemon's (never a config file found
    in the working directory). iceoryx2 joins its directory names to the root as to a string,
    so the root gets a trailing slash, as the daemon gives it."""
    cfg = iox2.config.default()
    # `global_cfg` returns a live view: setting its attributes changes `cfg` itself.
    cfg.global_cfg.prefix = iox2.FileName.new(prefix)
    cfg.global_cfg.root_path = iox2.Path.new(root if root.endswith("/") else root + "/")
    return cfg


def create_node(prefix: str, root: str, name: str):
    """A node under the daemon's prefix and root. iceoryx2's signal handling is off (as the
    daemon's): our own handlers (stop_flag) see SIGINT/SIGTERM."""
    iox2.set_log_level_from_env_or(iox2.LogLevel.Fatal)
    node = (
        iox2.NodeBuilder.new()
        .name(iox2.NodeName.new(name))
        .config(config(prefix, root))
        .signal_handling_mode(iox2.SignalHandlingMode.Disabled)
        .create(iox2.ServiceType.Ipc)
    )
    _restrict_global_segment(prefix)
    return node


# transport::names: a prefix ends in its only "_", so no prefix's files are another's; after it,
# the names iceoryx2 0.10 gives its segments in /dev/shm (H: a SHA-1 in hex, D: a u128).
_PREFIX = re.compile(r"[A-Za-z0-9][A-Za-z0-9.-]{0,62}_")
_SEGMENT = re.compile(
    r"[0-9a-f]{40}_(?:"
    r"\d{1,39}(?:__(?:\d{1,39}|mgmt))?\.data"
    r"|\d{1,39}\.(?:dynamic|event_mgmt|blackboard_mgmt|blackboard_data)"
    r"|\d{1,39}_\d{1,39}\.connection"
    r"|node\.\d{1,39}_\d{1,39}_\d{1,39}\.global_mgmt)"
)


def _own_segments(prefix: str):
    """This prefix's segments in /dev/shm: iceoryx2's names only, regular files of ours, never
    followed through a link (as transport::cleanup)."""
    try:
        names = os.listdir("/dev/shm")
    except OSError:
        return []
    me = os.geteuid()
    out = []
    for n in names:
        if not (n.startswith(prefix) and _SEGMENT.fullmatch(n[len(prefix):])):
            continue
        p = os.path.join("/dev/shm", n)
        try:
            st = os.stat(p, follow_symlinks=False)
        except OSError:
            continue
        if stat.S_ISREG(st.st_mode) and st.st_uid == me:
            out.append((p, st))
    return out


def _restrict_global_segment(prefix: str) -> None:
    """iceoryx2 0.10 makes the prefix's node counter in /dev/shm 0666; take that back, as the
    daemon does (docs/operations.md, "Users and permissions"), through the file itself."""
    for p, st in _own_segments(prefix):
        if p.endswith(".global_mgmt") and st.st_mode & 0o077:
            try:
                fd = os.open(p, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK)
            except OSError:
                continue
            try:
                if stat.S_ISREG(os.fstat(fd).st_mode):
                    os.fchmod(fd, 0o600)
            except OSError:
                pass
            finally:
                os.close(fd)


def remove_prefix_leftovers(prefix: str, root: str) -> None:
    """Once no node of the prefix is left, remove the files iceoryx2 leaves behind even after a
    clean exit (the prefix's `.global_mgmt` in /dev/shm), as transport::remove_prefix_leftovers:
    only its segments in /dev/shm, regular files of ours. Call it after every node of this
    process is gone."""
    try:
        if iox2.Node.list(iox2.ServiceType.Ipc, config(prefix, root)):
            return
    except Exception:  # noqa: BLE001 (cannot tell: leave everything)
        return
    shm = os.open("/dev/shm", os.O_RDONLY | os.O_DIRECTORY | os.O_NOFOLLOW)
    try:
        for p, _ in _own_segments(prefix):
            try:
                os.unlink(os.path.basename(p), dir_fd=shm)
            except OSError:
                pass
    finally:
        os.close(shm)


def stop_flag() -> list:
    """A one-element list that becomes [True] at SIGINT or SIGTERM (check it in loops)."""
    flag = [False]

    def on_signal(_sig, _frame):
        flag[0] = True

    signal.signal(signal.SIGINT, on_signal)
    signal.signal(signal.SIGTERM, on_signal)
    return flag


RAD_TO_DEG = 180.0 / math.pi
