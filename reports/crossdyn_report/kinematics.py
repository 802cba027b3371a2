"""Quaternion arithmetic on a run's attitude columns (numpy, row-wise), for the charts.

Quaternions are rows (w, x, y, z), scalar first, Hamilton product, R(q) v_B = v_N as in
core/system.hpp. The functions mirror core/rotation.cpp (angle_between, rotation_vector); they are
tested in tests/report/test_report_py.py against the runs' own joint angle columns."""

import numpy as np


def normalise(q):
    return q / np.linalg.norm(q, axis=1)[:, None]


def conj(q):
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def multiply(a, b):
    """Hamilton product a (x) b, row by row."""
    aw, av = a[:, :1], a[:, 1:]
    bw, bv = b[:, :1], b[:, 1:]
    w = aw * bw - np.sum(av * bv, axis=1, keepdims=True)
    v = aw * bv + bw * av + np.cross(av, bv)
    return np.hstack([w, v])


def rotation_vector(q):
    """The log map: axis times angle (rad, |phi| <= pi) of each unit quaternion (q and -q give the
    same vector)."""
    q = normalise(q)
    q = np.where(q[:, :1] < 0, -q, q)
    s = np.linalg.norm(q[:, 1:], axis=1)
    angle = 2.0 * np.arctan2(s, q[:, 0])
    # angle / s -> 2 as s -> 0 (first-order series of 2 atan2(s, w) / s with w -> 1).
    scale = np.where(s > 1e-12, angle / np.where(s > 1e-12, s, 1.0), 2.0 / np.maximum(q[:, 0], 1e-300))
    return q[:, 1:] * scale[:, None]


def attitude_angle(qa, qb):
    """Rotation angle (rad) between two attitudes given as rows of (w, x, y, z); q and -q agree.

    d = conj(qa) * qb; angle = 2 atan2(|vec d|, |w d|), accurate near zero where arccos of the dot
    product is not (the same formula as core/rotation.cpp angle_between)."""
    d = multiply(conj(normalise(qa)), normalise(qb))
    return 2.0 * np.arctan2(np.linalg.norm(d[:, 1:], axis=1), np.abs(d[:, 0]))


def attitude(run, body):
    cols = [body + s for s in (".qw", ".qx", ".qy", ".qz")]
    if not all(run.has(c) for c in cols):
        return None
    return np.column_stack([run.col(c) for c in cols])


def joint_rotation_vectors(run, system, joint):
    """Rotation vector phi (rad, joint frame) of the joint rotation of `joint` (a joint of the
    summary's system block) at every row of `run`, from the two bodies' attitudes:
        q_J = q_offset^-1 (x) q_NP^-1 (x) q_NC        (core/system.hpp: R_PC = R_offset R_J)
    Revolute: phi = angle * axis_J with axis_J = R_offset^T axis_P. None when the run lacks a column
    or the joint has no parent body (the free joint)."""
    names = {b["name"] for b in system.get("bodies", [])}
    if joint.get("parent") not in names:
        return None
    q_NP = attitude(run, joint["parent"])
    q_NC = attitude(run, joint["child"])
    if q_NP is None or q_NC is None:
        return None
    offset = np.asarray(joint.get("orientation_offset_q", [1.0, 0.0, 0.0, 0.0]), float)[None, :]
    q_J = multiply(conj(normalise(np.repeat(offset, q_NP.shape[0], axis=0))),
                   multiply(conj(normalise(q_NP)), normalise(q_NC)))
    return rotation_vector(q_J)
