#!/usr/bin/env python3
"""Writes the ROS 2 recording fixture for model-export's log tests.

Turns a simulated log of the default robot (`model-export simulate`) into what a ROS 2
robot records: a rosbag2 MCAP file whose /joint_states topic carries CDR-encoded
sensor_msgs/msg/JointState messages (header stamps with seeded jitter around the
controller period, joint names in another order than the robot's plus a gripper joint
the robot does not have, effort = joint torque), beside a second topic the reader must
skip. It also writes the same samples as a CSV log (time = stamp - first stamp, exactly
as the reader computes it), so that a test can check that both give the same figures.

No ROS installation is needed: the `mcap` package writes the file and the CDR bytes are
packed here (plain CDR, little endian, the layout every ROS 2 middleware records).

    python3 -m venv venv && venv/bin/pip install mcap
    cargo run -p model-export -- simulate --seeded-trajectory 1 --joints 4,5,6 --seed 1 -o /tmp/sim.csv
    venv/bin/python scripts/make_mcap_fixture.py /tmp/sim.csv robots/default.toml crates/logs/tests/fixtures

Outputs: joint_states.mcap and joint_states.csv (header t_s, q1..qN, qd1..qN, tau1..tauN).
"""
import csv
import random
import struct
import sys
import tomllib
from pathlib import Path

from mcap.writer import CompressionType, Writer

SEED = 20260
EPOCH_NS = 1_764_000_000 * 1_000_000_000  # stamps in the recent past, as on a robot
JITTER_NS = 400_000  # +-0.4 ms on a 10 ms controller period
TOPIC = "/joint_states"
EXTRA_JOINT = "gripper_finger_joint"

JOINT_STATE_MSGDEF = """std_msgs/Header header
string[] name
float64[] position
float64[] velocity
float64[] effort

================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id

================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
"""


class Cdr:
    """Plain CDR, little endian; alignment relative to the end of the 4-byte
    encapsulation header."""

    def __init__(self):
        self.buf = bytearray()

    def align(self, n):
        while len(self.buf) % n:
            self.buf.append(0)

    def pack(self, fmt, size, *v):
        self.align(size)
        self.buf += struct.pack("<" + fmt, *v)

    def string(self, s):
        b = s.encode() + b"\0"
        self.pack("I", 4, len(b))
        self.buf += b

    def strings(self, ss):
        self.pack("I", 4, len(ss))
        for s in ss:
            self.string(s)

    def doubles(self, vs):
        self.pack("I", 4, len(vs))
        for v in vs:
            self.pack("d", 8, v)

    def bytes(self):
        return b"\x00\x01\x00\x00" + bytes(self.buf)


def joint_state(stamp_ns, names, position, velocity, effort):
    c = Cdr()
    c.pack("i", 4, stamp_ns // 1_000_000_000)
    c.pack("I", 4, stamp_ns % 1_000_000_000)
    c.string("base_link")
    c.strings(names)
    c.doubles(position)
    c.doubles(velocity)
    c.doubles(effort)
    return c.bytes()


def string_msg(text):
    c = Cdr()
    c.string(text)
    return c.bytes()


def robot_joint_names(path: Path):
    """Moving joints of a DH robot file (the default robot), in order."""
    with open(path, "rb") as f:
        robot = tomllib.load(f)
    return [j["name"] for j in robot["joint"]]


def main(sim_csv: Path, robot: Path, out_dir: Path):
    names = robot_joint_names(robot)
    n = len(names)
    with open(sim_csv, newline="") as f:
        rows = list(csv.DictReader(f))
    rng = random.Random(SEED)
    # Message arrays: the robot's joints sorted by name, the gripper joint in the middle.
    order = sorted(names)
    order.insert(n // 2, EXTRA_JOINT)
    samples = []
    for r in rows:
        t_ns = round(float(r["t_s"]) * 1e9)
        stamp = EPOCH_NS + t_ns + rng.randint(-JITTER_NS, JITTER_NS)
        q = [float(r[f"q{j + 1}_rad"]) for j in range(n)]
        qd = [float(r[f"qd{j + 1}_rad_s"]) for j in range(n)]
        tau = [float(r[f"tau{j + 1}_nm"]) for j in range(n)]
        samples.append((stamp, q, qd, tau))

    out_dir.mkdir(parents=True, exist_ok=True)
    with open(out_dir / "joint_states.mcap", "wb") as f:
        w = Writer(f, compression=CompressionType.ZSTD)
        w.start(profile="ros2", library="scripts/make_mcap_fixture.py")
        js = w.register_schema(name="sensor_msgs/msg/JointState", encoding="ros2msg",
                               data=JOINT_STATE_MSGDEF.encode())
        st = w.register_schema(name="std_msgs/msg/String", encoding="ros2msg",
                               data=b"string data\n")
        ch = w.register_channel(topic=TOPIC, message_encoding="cdr", schema_id=js)
        mode = w.register_channel(topic="/robot_mode", message_encoding="cdr", schema_id=st)
        for k, (stamp, q, qd, tau) in enumerate(samples):
            by_name = {nm: (q[j], qd[j], tau[j]) for j, nm in enumerate(names)}
            by_name[EXTRA_JOINT] = (0.04, 0.0, 0.0)
            cols = [by_name[nm] for nm in order]
            data = joint_state(stamp, order, [c[0] for c in cols], [c[1] for c in cols],
                               [c[2] for c in cols])
            # Received (log time) 1-2 ms after the stamp, in order.
            log_time = stamp + 1_000_000 + rng.randint(0, 1_000_000)
            if k % 250 == 0:
                w.add_message(channel_id=mode, log_time=log_time, publish_time=log_time,
                              data=string_msg("RUNNING"), sequence=k // 250)
            w.add_message(channel_id=ch, log_time=log_time, publish_time=stamp, data=data,
                          sequence=k)
        w.finish()

    t0 = samples[0][0]
    with open(out_dir / "joint_states.csv", "w") as f:
        f.write(",".join(["t_s"] + [f"q{j + 1}_rad" for j in range(n)]
                         + [f"qd{j + 1}_rad_s" for j in range(n)]
                         + [f"tau{j + 1}_nm" for j in range(n)]) + "\n")
        for stamp, q, qd, tau in samples:
            # Exactly the reader's time: integer nanoseconds, one correctly rounded division.
            t = (stamp - t0) / 1e9
            f.write(",".join(repr(float(v)) for v in [t] + q + qd + tau) + "\n")
    print(f"wrote {out_dir}/joint_states.mcap and joint_states.csv ({len(samples)} messages)")


if __name__ == "__main__":
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    main(Path(sys.argv[1]), Path(sys.argv[2]), Path(sys.argv[3]))
