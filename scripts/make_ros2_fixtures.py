#!/usr/bin/env python3
"""Writes the ROS 2 recording fixtures of the rosbag2 folder, .db3, joint-map,
two-publisher and time-source tests, with the tools ROS 2 users have.

Every bag carries the samples of the committed log twin `joint_states.csv` (a simulated
run of the default robot, written by scripts/make_mcap_fixture.py), as
sensor_msgs/msg/JointState messages on /joint_states, stamped EPOCH + t exactly (integer
nanoseconds), so each reads back to the CSV's samples bit for bit:

- `default.db3`: sqlite3 storage (ROS 2 Humble/Iron), the robot's own joint names,
  written by the `rosbags` package (its rosbag2 writer and CDR serialiser);
- `ur_split/`: a rosbag2 folder of MCAP storage split in two files (as
  `ros2 bag record --max-bag-size` leaves it), joints named as the UR ROS 2 driver names
  them (`shoulder_pan_joint` ...), each part written by `rosbags`, the folder's
  metadata.yaml the first part's with both files listed;
- `two_publishers.mcap`: the arm's joints from two publishers (joints 1-3 and 4-6, as
  separate controllers publish them) and a gripper publisher at half the rate, written
  by the `mcap` + `mcap-ros2-support` packages (zstd chunks);
- `zero_stamps.mcap`: every header stamp zero (as some drivers leave it), the log time
  carrying the samples' times (`mcap-ros2-support`).

It also writes the seeds of the rosbag2-folder and .db3 fuzz targets (small bags of 20
messages, the same writers; a folder seed is framed as the fuzz target reads it: u32 LE
length + metadata.yaml, then u32 LE length + bytes of each storage file):

    pip install mcap mcap-ros2-support rosbags
    python3 scripts/make_ros2_fixtures.py crates/logs/tests/fixtures fuzz/corpus
"""
import csv
import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np
from mcap_ros2.writer import Writer as McapRos2Writer
from rosbags.rosbag2 import StoragePlugin, Writer
from rosbags.typesys import Stores, get_typestore
from ruamel.yaml import YAML

EPOCH_NS = 1_764_000_000 * 1_000_000_000
TOPIC = "/joint_states"
ROBOT = ["shoulder_pan", "shoulder_lift", "elbow", "wrist_1", "wrist_2", "wrist_3"]
UR = [f"{n}_joint" for n in ROBOT]
GRIPPER = "gripper_finger_joint"

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


def samples(csv_path):
    """(stamp_ns, q, qd, tau) per row of the CSV twin."""
    out = []
    with open(csv_path, newline="") as f:
        for r in csv.DictReader(f):
            t_ns = round(float(r["t_s"]) * 1e9)
            assert t_ns / 1e9 == float(r["t_s"]), "time not exact in nanoseconds"
            n = len(ROBOT)
            q = [float(r[f"q{j + 1}_rad"]) for j in range(n)]
            qd = [float(r[f"qd{j + 1}_rad_s"]) for j in range(n)]
            tau = [float(r[f"tau{j + 1}_nm"]) for j in range(n)]
            out.append((EPOCH_NS + t_ns, q, qd, tau))
    return out


def rosbags_write(folder, names, rows, storage):
    ts = get_typestore(Stores.ROS2_HUMBLE)
    js_t = ts.types["sensor_msgs/msg/JointState"]
    hdr_t = ts.types["std_msgs/msg/Header"]
    time_t = ts.types["builtin_interfaces/msg/Time"]
    with Writer(folder, version=9, storage_plugin=storage) as w:
        c = w.add_connection(TOPIC, js_t.__msgtype__, typestore=ts)
        for stamp, q, qd, tau in rows:
            msg = js_t(
                header=hdr_t(stamp=time_t(sec=stamp // 10**9, nanosec=stamp % 10**9),
                             frame_id="base_link"),
                name=list(names),
                position=np.array(q, dtype=np.float64),
                velocity=np.array(qd, dtype=np.float64),
                effort=np.array(tau, dtype=np.float64),
            )
            # Logged 1 ms after the stamp.
            w.write(c, stamp + 1_000_000, ts.serialize_cdr(msg, js_t.__msgtype__))


def joint_state(stamp, names, q, qd, tau):
    sec, nsec = divmod(stamp, 10**9)
    return {"header": {"stamp": {"sec": sec, "nanosec": nsec}, "frame_id": "base_link"},
            "name": names, "position": q, "velocity": qd, "effort": tau}


def main(out_dir: Path):
    rows = samples(out_dir / "joint_states.csv")
    tmp = Path(tempfile.mkdtemp())

    # default.db3: sqlite3 storage, the robot's joint names.
    rosbags_write(tmp / "db", ROBOT, rows, StoragePlugin.SQLITE3)
    shutil.copy(tmp / "db" / "db.db3", out_dir / "default.db3")

    # ur_split/: two MCAP parts with UR driver names.
    half = len(rows) // 2
    split = out_dir / "ur_split"
    shutil.rmtree(split, ignore_errors=True)
    split.mkdir()
    parts = []
    for i, part in enumerate([rows[:half], rows[half:]]):
        d = tmp / f"ur_split_{i}"
        rosbags_write(d, UR, part, StoragePlugin.MCAP)
        shutil.copy(d / f"ur_split_{i}.mcap", split / f"ur_split_{i}.mcap")
        yaml = YAML()
        parts.append(yaml.load((d / "metadata.yaml").read_text()))
    meta = parts[0]
    info = meta["rosbag2_bagfile_information"]
    info["relative_file_paths"] = [f"ur_split_{i}.mcap" for i in range(2)]
    info["files"] = [p["rosbag2_bagfile_information"]["files"][0] for p in parts]
    info["message_count"] = len(rows)
    info["topics_with_message_count"][0]["message_count"] = len(rows)
    first = info["starting_time"]["nanoseconds_since_epoch"]
    last = parts[1]["rosbag2_bagfile_information"]
    info["duration"]["nanoseconds"] = (last["starting_time"]["nanoseconds_since_epoch"]
                                       + last["duration"]["nanoseconds"] - first)
    with open(split / "metadata.yaml", "w") as f:
        YAML().dump(meta, f)

    # two_publishers.mcap: joints 1-3 and 4-6 from two publishers, a gripper at half rate.
    with open(out_dir / "two_publishers.mcap", "wb") as f:
        w = McapRos2Writer(f, chunk_size=32 * 1024)
        schema = w.register_msgdef("sensor_msgs/msg/JointState", JOINT_STATE_MSGDEF)
        for k, (stamp, q, qd, tau) in enumerate(rows):
            log = stamp + 1_000_000
            w.write_message(TOPIC, schema, joint_state(stamp, ROBOT[3:], q[3:], qd[3:], tau[3:]),
                            log_time=log, publish_time=log)
            w.write_message(TOPIC, schema, joint_state(stamp, ROBOT[:3], q[:3], qd[:3], tau[:3]),
                            log_time=log + 1000, publish_time=log + 1000)
            if k % 2 == 1:
                w.write_message(TOPIC, schema,
                                joint_state(stamp + 3_000_000, [GRIPPER], [0.04], [0.0], [0.0]),
                                log_time=log + 2000, publish_time=log + 2000)
        w.finish()

    # zero_stamps.mcap: header stamps zero, log time = the sample's time.
    with open(out_dir / "zero_stamps.mcap", "wb") as f:
        w = McapRos2Writer(f, chunk_size=32 * 1024)
        schema = w.register_msgdef("sensor_msgs/msg/JointState", JOINT_STATE_MSGDEF)
        for stamp, q, qd, tau in rows:
            w.write_message(TOPIC, schema, joint_state(0, ROBOT, q, qd, tau),
                            log_time=stamp, publish_time=stamp)
        w.finish()
    shutil.rmtree(tmp)


def frame(parts):
    out = b""
    for p in parts:
        out += len(p).to_bytes(4, "little") + p
    return out


def fuzz_seeds(fixtures: Path, corpus: Path):
    rows = samples(fixtures / "joint_states.csv")[:20]
    tmp = Path(tempfile.mkdtemp())
    (corpus / "db3").mkdir(parents=True, exist_ok=True)
    (corpus / "rosbag2_folder").mkdir(parents=True, exist_ok=True)
    rosbags_write(tmp / "db", ROBOT, rows, StoragePlugin.SQLITE3)
    shutil.copy(tmp / "db" / "db.db3", corpus / "db3" / "default.db3")
    # Split MCAP folder (UR names, read with the target's map) and a one-file sqlite3 folder.
    for i, part in enumerate([rows[:10], rows[10:]]):
        rosbags_write(tmp / f"p{i}", UR, part, StoragePlugin.MCAP)
    meta = (tmp / "p0" / "metadata.yaml").read_text().replace(
        "relative_file_paths:\n  - p0.mcap", "relative_file_paths:\n  - p0.mcap\n  - p1.mcap")
    (corpus / "rosbag2_folder" / "split_mcap.bin").write_bytes(frame(
        [meta.encode(), (tmp / "p0" / "p0.mcap").read_bytes(), (tmp / "p1" / "p1.mcap").read_bytes()]))
    (corpus / "rosbag2_folder" / "sqlite3.bin").write_bytes(frame(
        [(tmp / "db" / "metadata.yaml").read_bytes(), (tmp / "db" / "db.db3").read_bytes()]))
    shutil.rmtree(tmp)


if __name__ == "__main__":
    main(Path(sys.argv[1]))
    if len(sys.argv) > 2:
        fuzz_seeds(Path(sys.argv[1]), Path(sys.argv[2]))
