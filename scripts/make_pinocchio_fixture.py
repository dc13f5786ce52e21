#!/usr/bin/env python3
"""Writes the Pinocchio inverse-dynamics fixture for model-export's URDF tree tests.

Reads public arm URDFs with grippers as shipped in the `example-robot-data` package (the
Franka Emika Panda with its two prismatic fingers, the Kinova Jaco j2s6s200 with its
two-finger gripper, the Unitree Z1 with its revolute gripper jaw), strips the mesh
references (<visual> and <collision> elements: only kinematics and inertia matter here),
locks every joint outside the base-to-tip chain at a chosen position, draws 500 seeded
random states (q, qd, qdd) of the chain and writes Pinocchio's RNEA torques for them.

    python3 -m venv venv && venv/bin/pip install pin example-robot-data
    venv/bin/python scripts/make_pinocchio_fixture.py crates/robot/tests/fixtures/pinocchio

Outputs per robot NAME: NAME.urdf (stripped), NAME.json (base and tip link, positions of
the joints outside the chain, the chain's joint names, seed, Pinocchio version) and
NAME.csv (header q1..qn, qd1..qn, qdd1..qn, tau1..taun; SI units, shortest round-trip
decimals). Same inputs and seed give the same files.
"""
import json
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pinocchio as pin

STATES = 500
SEED = 20260519

# name: (path under example-robot-data/robots, tip link, positions of joints outside the chain)
ROBOTS = {
    "panda": (
        "panda_description/urdf/panda.urdf",
        "panda_hand",
        {"panda_finger_joint1": 0.02, "panda_finger_joint2": 0.035},
    ),
    "kinova_j2s6s200": (
        "kinova_description/robots/kinova.urdf",
        "j2s6s200_end_effector",
        {},
    ),
    "z1_gripper": (
        "z1_description/urdf/z1.urdf",
        "link06",
        {"jointGripper": -0.6},
    ),
}


def robots_dir():
    for p in sys.path:
        d = Path(p) / "cmeel.prefix" / "share" / "example-robot-data" / "robots"
        if d.is_dir():
            return d
    sys.exit("example-robot-data not found: pip install example-robot-data")


def stripped_urdf(path):
    tree = ET.parse(path)
    root = tree.getroot()
    for parent in root.iter():
        for child in list(parent):
            if child.tag in ("visual", "collision"):
                parent.remove(child)
    # Gazebo and transmission blocks are not part of the kinematic tree.
    for child in list(root):
        if child.tag in ("gazebo", "transmission"):
            root.remove(child)
    ET.indent(tree, "  ")
    return ET.tostring(root, encoding="unicode") + "\n"


def chain_joint_names(root, tip):
    """Moving joints from the root link to `tip`, base to tip."""
    parent_joint = {}
    for j in root.findall("joint"):
        parent_joint[j.find("child").get("link")] = j
    names = []
    link = tip
    while link in parent_joint:
        j = parent_joint[link]
        if j.get("type") != "fixed":
            names.append(j.get("name"))
        link = j.find("parent").get("link")
    return names[::-1], link


def make(name, rel, tip, side, out):
    text = stripped_urdf(robots_dir() / rel)
    (out / f"{name}.urdf").write_text(text)
    root = ET.fromstring(text)
    chain, base = chain_joint_names(root, tip)
    model = pin.buildModelFromXML(text)
    # Lock every joint not in the chain: at its given position, else 0.
    qref = pin.neutral(model)
    lock = []
    for jid in range(1, model.njoints):
        jname = model.names[jid]
        if jname in chain:
            continue
        j = model.joints[jid]
        q = side.get(jname, 0.0)
        if j.nq == 2:
            qref[j.idx_q : j.idx_q + 2] = [np.cos(q), np.sin(q)]
        else:
            qref[j.idx_q] = q
        lock.append(jid)
    missing = set(side) - {model.names[i] for i in lock}
    if missing:
        sys.exit(f"{name}: side joints not in the model outside the chain: {missing}")
    reduced = pin.buildReducedModel(model, lock, qref)
    data = reduced.createData()
    ids = [reduced.getJointId(n) for n in chain]
    rng = np.random.default_rng(SEED + sum(map(ord, name)))
    n = len(chain)
    rows = []
    for _ in range(STATES):
        q = np.empty(n)
        for k, jid in enumerate(ids):
            lo = reduced.lowerPositionLimit[reduced.joints[jid].idx_q]
            hi = reduced.upperPositionLimit[reduced.joints[jid].idx_q]
            if reduced.joints[jid].nq == 2 or not (np.isfinite(lo) and np.isfinite(hi)) or hi - lo > 2 * np.pi:
                lo, hi = -np.pi, np.pi
            q[k] = rng.uniform(lo, hi)
        qd = rng.uniform(-2.0, 2.0, n)
        qdd = rng.uniform(-6.0, 6.0, n)
        qp = pin.neutral(reduced)
        vp = np.zeros(reduced.nv)
        ap = np.zeros(reduced.nv)
        for k, jid in enumerate(ids):
            j = reduced.joints[jid]
            if j.nq == 2:
                qp[j.idx_q : j.idx_q + 2] = [np.cos(q[k]), np.sin(q[k])]
            else:
                qp[j.idx_q] = q[k]
            vp[j.idx_v] = qd[k]
            ap[j.idx_v] = qdd[k]
        tau = pin.rnea(reduced, data, qp, vp, ap)
        rows.append(list(q) + list(qd) + list(qdd) + [tau[reduced.joints[jid].idx_v] for jid in ids])
    header = [f"{p}{i + 1}" for p in ("q", "qd", "qdd", "tau") for i in range(n)]
    with open(out / f"{name}.csv", "w") as f:
        f.write(",".join(header) + "\n")
        for r in rows:
            f.write(",".join(repr(float(v)) for v in r) + "\n")
    meta = {
        "urdf": f"{name}.urdf",
        "source": f"example-robot-data robots/{rel}",
        "base_link": base,
        "tip_link": tip,
        "side_joints": side,
        "chain_joints": chain,
        "states": STATES,
        "seed": SEED,
        "pinocchio_version": pin.__version__,
    }
    (out / f"{name}.json").write_text(json.dumps(meta, indent=2) + "\n")
    print(f"{name}: {n} chain joints {chain}, {len(lock)} locked, {STATES} states")


def main():
    out = Path(sys.argv[1] if len(sys.argv) > 1 else "crates/robot/tests/fixtures/pinocchio")
    out.mkdir(parents=True, exist_ok=True)
    for name, (rel, tip, side) in ROBOTS.items():
        make(name, rel, tip, side, out)


if __name__ == "__main__":
    main()
