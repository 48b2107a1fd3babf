"""The control laws: what to command this cycle, given the reference and the estimate.

- :func:`default_law`: the default mode's delay-compensated dead-beat law in motor space
  (the command computed from the snapshot at s acts during [s+60, s+120) ms, the one in
  flight during [s, s+60)), with :func:`cartesian_rounding` and, at the end,
  :func:`hold_pulses`.
- :func:`thesis_law`: qdot = qdot_ref + K (q_ref - q), uniform saturation, rounding
  (docs/protocol.md, Thesis control loop, with its sign corrected).

Motor angles in rad, DH angles in rad, counts in 0.1 deg per 20 ms; six values each.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from manus.joint_map import dh_to_encoder_list
from manus.kinematics import jacobian_columns
from manus.quantize import (
    COUNT_RAD_S,
    JOINT_COUNT_MAX,
    ErrorFeedbackQuantizer,
    Quantizer,
    RoundingQuantizer,
    joint_rates_to_counts,
    saturate,
    saturate_values,
)
from services.controller.backlash import PlayModel
from services.controller.config import ControllerConfig
from services.controller.estimator import DriveEstimator, deadbeat_speed, lag_factor
from services.controller.reference import Reference

_CORNERS = np.array([[(k >> j) & 1 for j in range(6)] for k in range(64)], dtype=float)
"""Every floor/ceil choice of six joints, shape (64, 6): row k holds the bits b of k."""
_PAIRS = np.hstack([(_CORNERS[:, :, None] * _CORNERS[:, None, :]).reshape(64, 36), _CORNERS])
"""Per choice, the products b_i b_j (36, row-major) then the bits b_j (6): shape (64, 42)."""


def rounding_gains(
    q_target: Sequence[float], config: ControllerConfig, scale: float = 1.0
) -> np.ndarray:
    """Gripper error per motor error at ``q_target`` [rad]: G = J M (times ``scale``),
    shape (6, 6).

    J is the geometric Jacobian with its rotation rows weighted by ``rounding_rotation_m``
    [m/rad], M the motor-to-DH map (docs/protocol.md, Encoder map: dq2 = -de2,
    dq3 = de3 - de2), so column j is the gripper's (position [m], weighted rotation [m])
    change per radian of motor j.
    Built on plain floats from the closed-form Jacobian (NumPy's 6x6 calls cost more here).
    """
    p, w = scale, config.rounding_rotation_m * scale
    j1, j2, j3, j4, j5, j6 = jacobian_columns(q_target, config.arm)
    motor2 = tuple(-x - y for x, y in zip(j2, j3, strict=True))  # dq2 = -de2, dq3 = -de2
    flat: list[float] = []
    for a, b, c, zx, zy, zz in (j1, motor2, j3, j4, j5, j6):
        flat += (a * p, b * p, c * p, zx * w, zy * w, zz * w)
    return np.array(flat).reshape(6, 6).T


def cartesian_rounding(
    wanted: Sequence[float],
    miss: Sequence[float],
    gain: float,
    q_target: Sequence[float],
    config: ControllerConfig,
) -> np.ndarray:
    """Round each joint up or down so that the gripper, not each joint, lands nearest.

    Of the 64 floor/ceil choices lo + b (b in {0, 1}^6), take the one whose predicted
    motor error at the end of the command's cycle, mapped to the gripper through the
    Jacobian at the target, is smallest (position in m, orientation weighted by
    ``rounding_rotation_m`` [m/rad]), plus ``rounding_joint_m`` times each joint's own
    deviation from its ideal count.

    With A = gain G (:func:`rounding_gains`) the gripper error of a choice is
    A (base + b), base = miss / gain + lo, so its square is, up to a constant,
    b^T Q b + 2 (Q base)^T b with Q = A^T A; the joint term sum_j (lo_j + b_j - wanted_j)^2
    is, up to a constant, sum_j b_j (1 + 2 (lo_j - wanted_j)) (b_j^2 = b_j). Both are
    linear in the products b_i b_j and the bits b_j, so every choice's cost is one row of
    a single product with :data:`_PAIRS` (fewer NumPy calls: this runs every cycle).

    Args:
        wanted: ideal float counts, 6 values, within the range.
        miss: predicted motor error at the cycle's end with zero counts [rad], 6 values.
        gain: motor angle one count adds by the cycle's end [rad].
        q_target: DH target angles [rad], 6 values.
        config: controller settings.

    Returns:
        The counts, shape (6,) int64.
    """
    lo = [math.floor(v) for v in wanted]
    if max(lo) >= JOINT_COUNT_MAX or min(lo) < -JOINT_COUNT_MAX:
        return _clipped_rounding(wanted, miss, gain, q_target, config)
    At = rounding_gains(q_target, config, gain).T  # A^T, (motors, twist)
    Q = At @ At.T
    base = [m / gain + low for m, low in zip(miss, lo, strict=True)]
    k = (config.rounding_joint_m * gain) ** 2
    joint = [k * (1.0 + 2.0 * (low - v)) for low, v in zip(lo, wanted, strict=True)]
    best = int((_PAIRS @ np.concatenate((Q.ravel(), 2.0 * (Q @ base) + joint))).argmin())
    return np.array([low + ((best >> j) & 1) for j, low in enumerate(lo)], dtype=np.int64)


def _clipped_rounding(
    wanted: Sequence[float],
    miss: Sequence[float],
    gain: float,
    q_target: Sequence[float],
    config: ControllerConfig,
) -> np.ndarray:
    """:func:`cartesian_rounding` when a ceiling leaves the range (a count at exactly
    the limit): the candidates clipped, some of them twice."""
    cand = (_CORNERS + np.floor(wanted)).clip(-JOINT_COUNT_MAX, JOINT_COUNT_MAX)
    G = rounding_gains(q_target, config)
    err = G @ miss + gain * (cand @ G.T)
    cost = (err * err).sum(axis=1)
    cost += (config.rounding_joint_m * gain) ** 2 * ((cand - wanted) ** 2).sum(axis=1)
    best: np.ndarray = cand[int(cost.argmin())]
    return best.astype(np.int64)


def make_quantizer(name: str) -> Quantizer:
    """The quantizer called ``name`` (``rounding`` or ``error_feedback``)."""
    return ErrorFeedbackQuantizer() if name == "error_feedback" else RoundingQuantizer()


def default_law(
    cfg: ControllerConfig,
    ref: Reference,
    taus: tuple[float, float],
    scale: float,
    q: Sequence[float] | np.ndarray,
    est: DriveEstimator,
    play: PlayModel | None,
    quantizer: Quantizer,
    holding: bool,
) -> np.ndarray:
    """Counts for this cycle in the default mode, shape (6,) int64.

    Six values per quantity, on plain floats up to the rounding's 64 candidates (NumPy's
    per-call overhead on six values costs more than the arithmetic).

    Args:
        cfg: controller settings.
        ref: the reference followed.
        taus: its time when this command starts acting, and at the snapshot [s].
        scale: speed scale.
        q: measured DH angles [rad].
        est: the motor estimator, updated with this snapshot.
        play: belt-play model (None or inactive: no compensation).
        quantizer: rounding of the ``rounding`` / ``error_feedback`` settings.
        holding: the reference has ended: hold its end with :func:`hold_pulses`.
    """
    period = cfg.cycle_s
    tau_s = cfg.drive_tau_ms / 1000.0
    tau_cmd, tau_snap = taus
    if cfg.delay_compensation and est.x is not None:
        x1, v1 = est.predict(cfg.command_delay_ms / 1000.0)
        q_target = ref.position(tau_cmd + scale * period)
        target = dh_to_encoder_list(q_target)
        if play is not None and play.active:
            target = play.motor_target(np.array(target), np.array(x1)).tolist()
        if holding:
            return hold_pulses(cfg, x1, v1, target, q_target)
        u = deadbeat_speed(x1, v1, target, period, tau_s)
        if cfg.default_quantizer == "cartesian":
            wanted = saturate_values([v / COUNT_RAD_S for v in u], float(JOINT_COUNT_MAX))
            lag = lag_factor(tau_s, period)
            gain = (period - lag) * COUNT_RAD_S
            miss = [x + v * lag - t for x, v, t in zip(x1, v1, target, strict=True)]  # 0 counts
            return cartesian_rounding(wanted, miss, gain, q_target, cfg)
    else:
        # For comparison only: aim from the reading as if the command acted at once.
        target = dh_to_encoder_list(ref.position(tau_snap + scale * period))
        now = dh_to_encoder_list([float(v) for v in q])
        u = [(t - e) / period for t, e in zip(target, now, strict=True)]
    return quantizer(np.array(saturate_values([v / COUNT_RAD_S for v in u])))


def hold_pulses(
    cfg: ControllerConfig,
    x1: Sequence[float],
    v1: Sequence[float],
    target: Sequence[float],
    q_target: Sequence[float],
) -> np.ndarray:
    """Holding the end: one-cycle pulses between rests, so no limit cycle.

    With zero from now on the motors would rest at x1 + v1 tau; a pulse of n counts for
    one cycle moves a motor n x 0.3 deg further once its transient has died out. Choose
    the pulses (Cartesian-aware) that bring that rest nearest the target: at the optimum
    the best pulse is zero, and the arm stays.
    """
    tau = cfg.drive_tau_ms / 1000.0
    rest = [x + v * tau for x, v in zip(x1, v1, strict=True)]
    gain = cfg.cycle_s * COUNT_RAD_S
    top = float(JOINT_COUNT_MAX)
    wanted = [min(max((t - r) / gain, -top), top) for t, r in zip(target, rest, strict=True)]
    miss = [r - t for r, t in zip(rest, target, strict=True)]
    return cartesian_rounding(wanted, miss, gain, q_target, cfg)


def thesis_law(
    cfg: ControllerConfig, ref: Reference, tau: float, scale: float, q: np.ndarray
) -> np.ndarray:
    """Counts of the thesis's loop at reference time ``tau`` [s] from the snapshot ``q``."""
    s = ref.sample(tau)
    qdot = s.qd * scale + cfg.thesis_gain * (s.q - q)
    return RoundingQuantizer()(saturate(joint_rates_to_counts(qdot)))
