#!/usr/bin/env python3
"""Writes the Pinocchio fixture of a URDF with <mimic> joints for the robot crate's tests.

A hand-written 3-joint arm carrying a two-finger gripper in the style of a Robotiq 2F
(one driven knuckle, `finger_joint`; the other knuckle and an inner finger follow it
through <mimic> with multipliers -1 and 1 and an offset), heavy enough fingers that their
pose matters. Pinocchio (`buildModelFromXML(..., mimic=True)`) is the reference: the
master held at FINGER_Q rad with zero speed and acceleration, 200 seeded random states of
the arm, `pinocchio.rnea` on the full model, the arm's torques kept. As a cross-check the
same torques are computed without mimic support, every gripper joint locked at
`multiplier * FINGER_Q + offset` (`buildReducedModel`), and must agree to 1e-12.

    venv/bin/pip install pin
    venv/bin/python scripts/make_pinocchio_mimic_fixture.py crates/robot/tests/fixtures/pinocchio

Outputs mimic_gripper.urdf, mimic_gripper.json (base and tip link, the master's position,
chain joints, seed, Pinocchio version) and mimic_gripper.csv (header q1..qn, qd1..qn,
qdd1..qn, tau1..taun; SI units, shortest round-trip decimals).
"""
import json
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin

STATES = 200
SEED = 20261129
FINGER_Q = 0.62


def inertial(m, c, i):
    return (
        f'    <inertial><origin xyz="{c}" rpy="0.1 -0.2 0.3"/><mass value="{m}"/>'
        f'<inertia ixx="{i[0]}" ixy="{i[3]}" ixz="{i[4]}" iyy="{i[1]}" iyz="{i[5]}" izz="{i[2]}"/></inertial>\n'
    )


def link(name, m, c, i):
    return f'  <link name="{name}">\n{inertial(m, c, i)}  </link>\n'


def joint(name, kind, parent, child, xyz, rpy, axis, extra=""):
    return (
        f'  <joint name="{name}" type="{kind}">\n'
        f'    <parent link="{parent}"/><child link="{child}"/>\n'
        f'    <origin xyz="{xyz}" rpy="{rpy}"/><axis xyz="{axis}"/>\n'
        f'    <limit lower="-2.8" upper="2.8" effort="100" velocity="3"/>\n{extra}'
        f'  </joint>\n'
    )


def urdf():
    s = '<?xml version="1.0"?>\n<robot name="mimic_gripper">\n  <link name="base"/>\n'
    s += link("l1", 3.0, "0.01 0.02 0.1", (0.03, 0.028, 0.01, 0.001, 0.0, 0.002))
    s += joint("j1", "revolute", "base", "l1", "0 0 0.1", "0 0 0", "0 0 1")
    s += link("l2", 2.5, "0.2 0.0 0.01", (0.01, 0.05, 0.05, 0.0, 0.003, 0.0))
    s += joint("j2", "revolute", "l1", "l2", "0 0.05 0.2", "1.5708 0 0", "0 0 1")
    s += link("l3", 1.5, "0.15 0.01 0.0", (0.006, 0.02, 0.02, 0.001, 0.0, 0.0))
    s += joint("j3", "revolute", "l2", "l3", "0.4 0 0", "0 0 0.3", "0 0 1")
    # The gripper: a palm fixed to l3, a driven knuckle and two following ones.
    s += link("palm", 0.8, "0.0 0.0 0.04", (0.002, 0.002, 0.001, 0.0, 0.0, 0.0))
    s += joint("palm_joint", "fixed", "l3", "palm", "0.3 0 0", "0 1.5708 0", "0 0 1")
    s += link("left_knuckle", 0.6, "0.0 0.05 0.03", (0.001, 0.0008, 0.0009, 0.0, 0.0, 0.0001))
    s += joint("finger_joint", "revolute", "palm", "left_knuckle", "0 0.03 0.06", "0 0 0", "1 0 0")
    s += link("right_knuckle", 0.6, "0.0 -0.05 0.03", (0.001, 0.0008, 0.0009, 0.0, 0.0, 0.0001))
    s += joint("right_knuckle_joint", "revolute", "palm", "right_knuckle", "0 -0.03 0.06", "0 0 0", "1 0 0",
               '    <mimic joint="finger_joint" multiplier="-1" offset="0"/>\n')
    s += link("left_inner_finger", 0.4, "0.0 0.02 0.05", (0.0005, 0.0004, 0.0003, 0.0, 0.0, 0.0))
    s += joint("left_inner_finger_joint", "revolute", "left_knuckle", "left_inner_finger", "0 0.06 0.04", "0 0 0", "1 0 0",
               '    <mimic joint="finger_joint" multiplier="1" offset="0.1"/>\n')
    s += "</robot>\n"
    return s


def main():
    out = Path(sys.argv[1] if len(sys.argv) > 1 else "crates/robot/tests/fixtures/pinocchio")
    text = urdf()
    (out / "mimic_gripper.urdf").write_text(text)
    chain = ["j1", "j2", "j3"]
    side = {"finger_joint": FINGER_Q}
    mimic = pin.buildModelFromXML(text, mimic=True)
    plain = pin.buildModelFromXML(text)
    locked_q = {"finger_joint": FINGER_Q, "right_knuckle_joint": -FINGER_Q, "left_inner_finger_joint": FINGER_Q + 0.1}
    qref = pin.neutral(plain)
    lock = []
    for jid in range(1, plain.njoints):
        n = plain.names[jid]
        if n not in chain:
            qref[plain.joints[jid].idx_q] = locked_q[n]
            lock.append(jid)
    reduced = pin.buildReducedModel(plain, lock, qref)
    dm, dr = mimic.createData(), reduced.createData()
    rng = np.random.default_rng(SEED)
    rows, worst = [], 0.0
    for _ in range(STATES):
        q = rng.uniform(-2.5, 2.5, 3)
        qd = rng.uniform(-2.0, 2.0, 3)
        qdd = rng.uniform(-6.0, 6.0, 3)
        qm, vm, am = pin.neutral(mimic), np.zeros(mimic.nv), np.zeros(mimic.nv)
        qm[mimic.joints[mimic.getJointId("finger_joint")].idx_q] = FINGER_Q
        for k, n in enumerate(chain):
            j = mimic.joints[mimic.getJointId(n)]
            qm[j.idx_q], vm[j.idx_v], am[j.idx_v] = q[k], qd[k], qdd[k]
        tm = pin.rnea(mimic, dm, qm, vm, am)
        tau = [tm[mimic.joints[mimic.getJointId(n)].idx_v] for n in chain]
        qr, vr, ar = pin.neutral(reduced), np.zeros(reduced.nv), np.zeros(reduced.nv)
        for k, n in enumerate(chain):
            j = reduced.joints[reduced.getJointId(n)]
            qr[j.idx_q], vr[j.idx_v], ar[j.idx_v] = q[k], qd[k], qdd[k]
        tr = pin.rnea(reduced, dr, qr, vr, ar)
        tr = [tr[reduced.joints[reduced.getJointId(n)].idx_v] for n in chain]
        worst = max(worst, max(abs(a - b) for a, b in zip(tau, tr)))
        rows.append(list(q) + list(qd) + list(qdd) + tau)
    if worst > 1e-12:
        sys.exit(f"mimic model and locked positions disagree by {worst} N m")
    header = [f"{p}{i + 1}" for p in ("q", "qd", "qdd", "tau") for i in range(3)]
    with open(out / "mimic_gripper.csv", "w") as f:
        f.write(",".join(header) + "\n")
        for r in rows:
            f.write(",".join(repr(float(v)) for v in r) + "\n")
    meta = {
        "urdf": "mimic_gripper.urdf",
        "source": "scripts/make_pinocchio_mimic_fixture.py (hand-written)",
        "base_link": "base",
        "tip_link": "l3",
        "side_joints": side,
        "chain_joints": chain,
        "states": STATES,
        "seed": SEED,
        "pinocchio_version": pin.__version__,
    }
    (out / "mimic_gripper.json").write_text(json.dumps(meta, indent=2) + "\n")
    print(f"mimic_gripper: {STATES} states; mimic model vs locked positions {worst:.1e} N m")


if __name__ == "__main__":
    main()
