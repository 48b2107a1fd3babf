"""Closed-form inverse kinematics: every branch of a pose, and the one nearest a
configuration within the joint limits.

The derivation is in :mod:`manus.kinematics` (wrist centre, shoulder, elbow and wrist
branches). :func:`ik_all` (scalar, :mod:`math`) and :func:`ik_batch` (NumPy, many poses)
share formulas and branch order.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from manus.config import N_JOINTS, ArmConfig
from manus.errors import KinematicsError

TWO_PI = 2.0 * math.pi


class IkSolutions(NamedTuple):
    """All closed-form IK branches of one pose.

    Attributes:
        q: joint angles [rad], shape (k, 6), each wrapped to (-pi, pi]; k <= 8.
        branch: the branch of each row, shape (k, 3): (shoulder, elbow, wrist), each +-1.
    """

    q: np.ndarray
    branch: np.ndarray


def wrap(angle: np.ndarray | float) -> np.ndarray:
    """Angles wrapped to (-pi, pi]."""
    a = np.asarray(angle, dtype=float)
    return np.asarray(np.pi - np.mod(np.pi - a, TWO_PI))


def _describe(T: np.ndarray) -> str:
    p = T[:3, 3] * 1000.0
    return f"pose ({p[0]:.1f}, {p[1]:.1f}, {p[2]:.1f}) mm"


# Branch order of the rows of :func:`ik_batch`: (shoulder, elbow, wrist) signs.
BRANCHES = np.array([(s, e, w) for s in (1, -1) for e in (1, -1) for w in (1, -1)], dtype=int)


class IkBatch(NamedTuple):
    """Closed-form IK of many poses, every branch.

    Attributes:
        q: joint angles [rad] wrapped to (-pi, pi], shape (N, 8, 6); rows of invalid
            branches hold NaN.
        valid: which branches exist, shape (N, 8); row k is branch ``BRANCHES[k]``.
    """

    q: np.ndarray
    valid: np.ndarray


def ik_batch(T: np.ndarray, cfg: ArmConfig) -> IkBatch:
    """Every closed-form IK branch of each pose in ``T``, shape (N, 4, 4) [m].

    Vectorised over poses; joint limits are not applied. At an exact wrist singularity
    (sin q5 = 0) the two wrist branches coincide: the first keeps q4 = 0 and the whole
    turn goes to q6, the second is marked invalid.
    """
    T = np.asarray(T, dtype=float).reshape(-1, 4, 4)
    n = T.shape[0]
    R = T[:, :3, :3]
    p_w = T[:, :3, 3] - cfg.l4 * R[:, :, 2]
    px, py, pz = p_w[:, 0], p_w[:, 1], p_w[:, 2]
    rho2 = px * px + py * py - cfg.l1 * cfg.l1
    rho = np.sqrt(np.maximum(rho2, 0.0))
    v = -pz
    c = (rho2 + v * v - cfg.l2**2 - cfg.l3**2) / (2.0 * cfg.l2 * cfg.l3)
    reach_ok = (rho2 >= -1e-12) & (np.abs(c) <= 1.0 + 1e-12)
    acos_c = np.arccos(np.clip(c, -1.0, 1.0))
    q = np.full((n, 8, 6), np.nan)
    valid = np.zeros((n, 8), dtype=bool)
    phi = np.arctan2(py, px)
    for k4 in range(4):
        shoulder = 1 if k4 < 2 else -1
        elbow = 1 if k4 % 2 == 0 else -1
        u = shoulder * rho
        q1 = phi - np.arctan2(cfg.l1, u)
        tb = elbow * acos_c
        q3 = tb + np.pi / 2
        q2 = np.arctan2(v, u) - np.arctan2(cfg.l3 * np.sin(tb), cfg.l2 + cfg.l3 * np.cos(tb))
        # R03 = Rz(q1) Rx(-90) Rz(q2 + q3) Rx(+90), written out.
        c1, s1 = np.cos(q1), np.sin(q1)
        c23, s23 = np.cos(q2 + q3), np.sin(q2 + q3)
        R03 = np.empty((n, 3, 3))
        R03[:, 0, 0] = c1 * c23
        R03[:, 0, 1] = -s1
        R03[:, 0, 2] = c1 * s23
        R03[:, 1, 0] = s1 * c23
        R03[:, 1, 1] = c1
        R03[:, 1, 2] = s1 * s23
        R03[:, 2, 0] = -s23
        R03[:, 2, 1] = 0.0
        R03[:, 2, 2] = c23
        R36 = np.einsum("nji,njk->nik", R03, R)
        s5 = np.hypot(R36[:, 0, 2], R36[:, 1, 2])
        singular = s5 < 1e-12
        for w_index, wrist in enumerate((1, -1)):
            row = 2 * k4 + w_index
            # Same formulas as the scalar :func:`ik_all`: R36 = Rz(q4) Ry(q5) Rz(q6).
            q4 = np.where(singular, 0.0, np.arctan2(wrist * R36[:, 1, 2], wrist * R36[:, 0, 2]))
            q5 = np.arctan2(wrist * s5, R36[:, 2, 2])
            c4, s4, c5, sn5 = np.cos(q4), np.sin(q4), np.cos(q5), np.sin(q5)
            q6 = np.arctan2(
                -s4 * R36[:, 0, 0] + c4 * R36[:, 1, 0],
                c5 * (c4 * R36[:, 0, 0] + s4 * R36[:, 1, 0]) - sn5 * R36[:, 2, 0],
            )
            q[:, row] = np.stack([q1, q2, q3, q4, q5, q6], axis=-1)
            valid[:, row] = reach_ok & ~(singular & (w_index == 1))
    q = np.where(valid[:, :, None], wrap(q), np.nan)
    return IkBatch(q, valid)


def ik_all(T: np.ndarray, cfg: ArmConfig) -> IkSolutions:
    """Every closed-form IK branch of the gripper pose ``T`` (4x4, m).

    The scalar twin of :func:`ik_batch` (same formulas and branch order, written with
    :mod:`math` because NumPy's per-call overhead dominates for one pose; a test keeps
    the two equal). Joint limits are not applied here (see :func:`ik_nearest`). A wrist
    exactly at its singularity (sin q5 = 0) yields one wrist branch with q4 = 0;
    near-singular poses are solved exactly and flagged by :func:`is_wrist_singular`.

    Raises:
        KinematicsError: ``reason="unreachable"`` when no branch exists, saying why.
    """
    T = np.asarray(T, dtype=float)
    (r00, _, r02, x), (r10, _, r12, y), (r20, _, r22, z) = T[:3].tolist()
    px, py, pz = x - cfg.l4 * r02, y - cfg.l4 * r12, z - cfg.l4 * r22
    rho2 = px * px + py * py - cfg.l1 * cfg.l1
    c = (rho2 + pz * pz - cfg.l2**2 - cfg.l3**2) / (2.0 * cfg.l2 * cfg.l3)
    if rho2 < -1e-12 or abs(c) > 1.0 + 1e-12:
        raise _unreachable(T, cfg)
    rho = math.sqrt(max(rho2, 0.0))
    acos_c = math.acos(max(-1.0, min(1.0, c)))
    phi = math.atan2(py, px)
    v = -pz
    rows: list[list[float]] = []
    branches: list[tuple[int, int, int]] = []
    for shoulder in (1, -1):
        u = shoulder * rho
        q1 = phi - math.atan2(cfg.l1, u)
        c1, s1 = math.cos(q1), math.sin(q1)
        for elbow in (1, -1):
            tb = elbow * acos_c
            q3 = tb + math.pi / 2
            q2 = math.atan2(v, u) - math.atan2(
                cfg.l3 * math.sin(tb), cfg.l2 + cfg.l3 * math.cos(tb)
            )
            c23, s23 = math.cos(q2 + q3), math.sin(q2 + q3)
            # R36 = R03^T R with R03 = [[c1 c23, -s1, c1 s23], [s1 c23, c1, s1 s23], [-s23, 0, c23]]
            a00 = c1 * c23 * r00 + s1 * c23 * r10 - s23 * r20
            a02 = c1 * c23 * r02 + s1 * c23 * r12 - s23 * r22
            a10 = -s1 * r00 + c1 * r10
            a12 = -s1 * r02 + c1 * r12
            a20 = c1 * s23 * r00 + s1 * s23 * r10 + c23 * r20
            a22 = c1 * s23 * r02 + s1 * s23 * r12 + c23 * r22
            s5 = math.hypot(a02, a12)
            singular = s5 < 1e-12
            for wrist in (1,) if singular else (1, -1):
                # R36 = Rz(q4) Ry(q5) Rz(q6): q4 and q5 from its third column, q6 from
                # Rz(q6) = Ry(q5)^T Rz(q4)^T R36, which stays exact near the singularity.
                q4 = 0.0 if singular else math.atan2(wrist * a12, wrist * a02)
                q5 = math.atan2(wrist * s5, a22)
                c4, s4, c5, sn5 = math.cos(q4), math.sin(q4), math.cos(q5), math.sin(q5)
                q6 = math.atan2(-s4 * a00 + c4 * a10, c5 * (c4 * a00 + s4 * a10) - sn5 * a20)
                rows.append([q1, q2, q3, q4, q5, q6])
                branches.append((shoulder, elbow, wrist))
    return IkSolutions(wrap(np.array(rows)), np.array(branches, dtype=int))


def _unreachable(T: np.ndarray, cfg: ArmConfig) -> KinematicsError:
    p_w = T[:3, 3] - cfg.l4 * T[:3, 2]
    horizontal = math.hypot(p_w[0], p_w[1])
    if horizontal < cfg.l1:
        return KinematicsError(
            f"{_describe(T)} is unreachable: wrist centre {horizontal * 1000:.1f} mm from the "
            f"base axis, inside the shoulder offset L1 = {cfg.l1 * 1000:.1f} mm",
            reason="unreachable",
        )
    reach = math.sqrt(horizontal**2 - cfg.l1**2 + p_w[2] ** 2)
    far = reach > cfg.l2 + cfg.l3
    kind = "beyond the arm's reach" if far else "too close to the shoulder"
    return KinematicsError(
        f"{_describe(T)} is unreachable: wrist centre {reach * 1000:.1f} mm from the shoulder "
        f"is {kind} (reach {abs(cfg.l2 - cfg.l3) * 1000:.1f}..{(cfg.l2 + cfg.l3) * 1000:.1f} mm)",
        reason="unreachable",
        value=reach,
        limit=(cfg.l2 + cfg.l3) if far else abs(cfg.l2 - cfg.l3),
    )


def unwrap_near(q: np.ndarray, ref: np.ndarray) -> np.ndarray:
    """Each angle of ``q`` moved by whole turns to lie within pi of ``ref`` [rad], (..., 6)."""
    q = np.asarray(q, dtype=float)
    return np.asarray(ref + wrap(q - ref))


def _fit_limits(q: np.ndarray, ref: np.ndarray, cfg: ArmConfig) -> np.ndarray | None:
    """The turn-shifted copy of ``q`` nearest ``ref`` that lies within the limits, or None."""
    near = unwrap_near(q, ref)
    out = near.copy()
    for j in range(N_JOINTS):
        lo, hi = cfg.lower[j], cfg.upper[j]
        if lo <= out[j] <= hi:
            continue
        candidates = [near[j] + k * TWO_PI for k in (-2, -1, 1, 2)]
        inside = [c for c in candidates if lo <= c <= hi]
        if not inside:
            return None
        out[j] = min(inside, key=lambda c: abs(c - ref[j]))
    return out


def ik_nearest(
    T: np.ndarray,
    near: np.ndarray,
    cfg: ArmConfig,
    *,
    allow_singular: bool = False,
) -> np.ndarray:
    """The IK branch nearest ``near`` (rad, shape (6,)), unwrapped to its neighbourhood.

    "Nearest" is the smallest largest single-joint move (infinity norm). Branches that
    break a joint limit are skipped.

    Raises:
        KinematicsError: unreachable; ``reason="singular"`` when the chosen branch has the
            wrist within ``cfg.singular_tol`` of its singularity (unless ``allow_singular``);
            or every branch beyond a joint limit (the error names the joint, its value and
            the limit of the nearest such branch).
    """
    ref = np.asarray(near, dtype=float)
    sols = ik_all(T, cfg)
    best: np.ndarray | None = None
    best_cost = math.inf
    violation: tuple[int, float, float] | None = None
    for row in sols.q:
        fitted = _fit_limits(row, ref, cfg)
        if fitted is None:
            near_row = unwrap_near(row, ref)
            for j in range(N_JOINTS):
                if not cfg.lower[j] <= near_row[j] <= cfg.upper[j]:
                    lim = cfg.lower[j] if near_row[j] < cfg.lower[j] else cfg.upper[j]
                    if violation is None:
                        violation = (j + 1, float(near_row[j]), lim)
                    break
            continue
        cost = float(np.max(np.abs(fitted - ref)))
        if cost < best_cost:
            best, best_cost = fitted, cost
    if best is None:
        assert violation is not None
        j, val, lim = violation
        raise KinematicsError(
            f"{_describe(T)}: every IK branch breaks a joint limit; nearest: joint {j} at "
            f"{math.degrees(val):.1f} deg, limit {math.degrees(lim):.1f} deg",
            reason="joint_limit",
            joint=j,
            value=val,
            limit=lim,
        )
    if not allow_singular and is_wrist_singular(best, cfg):
        raise KinematicsError(
            f"{_describe(T)} is at a wrist singularity: "
            f"joint 5 at {math.degrees(best[4]):.3f} deg, "
            f"|sin q5| below {cfg.singular_tol:g} (joints 4 and 6 aligned)",
            reason="singular",
            joint=5,
            value=float(best[4]),
            limit=cfg.singular_tol,
        )
    return best


def branch_of(q: np.ndarray, cfg: ArmConfig) -> tuple[int, int, int]:
    """The (shoulder, elbow, wrist) branch signs of a configuration [rad]."""
    u = cfg.l2 * math.cos(q[1]) + cfg.l3 * math.sin(q[1] + q[2])
    shoulder = 1 if u >= 0 else -1
    elbow = 1 if math.sin(q[2] - math.pi / 2) >= 0 else -1
    wrist = 1 if math.sin(q[4]) >= 0 else -1
    return shoulder, elbow, wrist


def is_wrist_singular(q: np.ndarray, cfg: ArmConfig) -> bool:
    """True when joint 5 is within ``cfg.singular_tol`` of 0 or pi (q4 and q6 aligned)."""
    return abs(math.sin(float(q[4]))) < cfg.singular_tol
