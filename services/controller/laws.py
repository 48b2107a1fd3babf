"""The control laws: what to command this cycle, given the reference and the estimate.

- :func:`default_law`: the default mode's delay-compensated dead-beat law in motor space
  (the command computed from the snapshot at s acts during [s+60, s+120) ms, the one in
  flight during [s, s+60)), with :func:`cartesian_rounding` and, at the end,
  :func:`hold_pulses`.
- :func:`thesis_law`: qdot = qdot_ref + K (q_ref - q), uniform saturation, rounding
  (thesis 4.2.3.4 with its sign corrected).

Motor angles in rad, DH angles in rad, counts in 0.1 deg per 20 ms; arrays shape (6,).
"""

from __future__ import annotations

import numpy as np

from manus.joint_map import M_ENCODER_TO_DH, dh_to_encoder
from manus.kinematics import chain
from manus.quantize import (
    COUNT_RAD_S,
    JOINT_COUNT_MAX,
    ErrorFeedbackQuantizer,
    Quantizer,
    RoundingQuantizer,
    joint_rates_to_counts,
    saturate,
)
from services.controller.backlash import PlayModel
from services.controller.config import ControllerConfig
from services.controller.estimator import DriveEstimator, deadbeat_speed, lag_factor
from services.controller.reference import Reference

_CORNERS = np.array([[(k >> j) & 1 for j in range(6)] for k in range(64)], dtype=float)
"""Every floor/ceil choice of six joints, shape (64, 6)."""


def cartesian_rounding(
    wanted: np.ndarray,
    miss: np.ndarray,
    gain: float,
    q_target: np.ndarray,
    config: ControllerConfig,
) -> np.ndarray:
    """Round each joint up or down so that the gripper, not each joint, lands nearest.

    Of the 64 floor/ceil choices, take the one whose predicted motor error at the end of
    the command's cycle, mapped to the gripper through the Jacobian at the target, is
    smallest (position in m, orientation weighted by ``rounding_rotation_m`` [m/rad]).

    Args:
        wanted: ideal float counts, shape (6,), within the range.
        miss: predicted motor error at the cycle's end with zero counts [rad], shape (6,).
        gain: motor angle one count adds by the cycle's end [rad].
        q_target: DH target angles [rad], shape (6,).
        config: controller settings.
    """
    lo = np.floor(wanted)
    cand = (lo + _CORNERS).clip(-JOINT_COUNT_MAX, JOINT_COUNT_MAX)  # (64, 6)
    # Gripper error per motor error: the weighted Jacobian at the target, coupling included.
    J = chain(q_target, config.arm).jacobian()
    J[3:] *= config.rounding_rotation_m
    G = J @ M_ENCODER_TO_DH
    # The gripper error of each choice, (64, 6): G (miss + gain cand), all in one product.
    err = G @ miss + gain * (cand @ G.T)
    cost = (err * err).sum(axis=1)
    # Rounding a joint away from its own nearest count costs too (no wrist chatter).
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
    q: np.ndarray,
    est: DriveEstimator,
    play: PlayModel | None,
    quantizer: Quantizer,
    holding: bool,
) -> np.ndarray:
    """Counts for this cycle in the default mode.

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
        q_target = ref.sample(tau_cmd + scale * period).q
        target = dh_to_encoder(q_target)
        if play is not None and play.active:
            target = play.motor_target(target, x1)
        if holding:
            return hold_pulses(cfg, x1, v1, target, q_target)
        u = deadbeat_speed(x1, v1, target, period, tau_s)
        if cfg.default_quantizer == "cartesian":
            wanted = saturate(u / COUNT_RAD_S, float(JOINT_COUNT_MAX))
            gain = (period - lag_factor(tau_s, period)) * COUNT_RAD_S
            miss = x1 + v1 * lag_factor(tau_s, period) - target  # at zero counts
            return cartesian_rounding(wanted, miss, gain, q_target, cfg)
    else:
        # For comparison only: aim from the reading as if the command acted at once.
        target = dh_to_encoder(ref.sample(tau_snap + scale * period).q)
        u = (target - dh_to_encoder(q)) / period
    return quantizer(saturate(u / COUNT_RAD_S, float(JOINT_COUNT_MAX)))


def hold_pulses(
    cfg: ControllerConfig,
    x1: np.ndarray,
    v1: np.ndarray,
    target: np.ndarray,
    q_target: np.ndarray,
) -> np.ndarray:
    """Holding the end: one-cycle pulses between rests, so no limit cycle.

    With zero from now on the motors would rest at x1 + v1 tau; a pulse of n counts for
    one cycle moves a motor n x 0.3 deg further once its transient has died out. Choose
    the pulses (Cartesian-aware) that bring that rest nearest the target: at the optimum
    the best pulse is zero, and the arm stays.
    """
    rest = x1 + v1 * (cfg.drive_tau_ms / 1000.0)
    gain = cfg.cycle_s * COUNT_RAD_S
    wanted = np.clip((target - rest) / gain, -JOINT_COUNT_MAX, JOINT_COUNT_MAX)
    return cartesian_rounding(wanted, rest - target, gain, q_target, cfg)


def thesis_law(
    cfg: ControllerConfig, ref: Reference, tau: float, scale: float, q: np.ndarray
) -> np.ndarray:
    """Counts of the thesis's loop at reference time ``tau`` [s] from the snapshot ``q``."""
    s = ref.sample(tau)
    qdot = s.qd * scale + cfg.thesis_gain * (s.q - q)
    return RoundingQuantizer()(saturate(joint_rates_to_counts(qdot)))
