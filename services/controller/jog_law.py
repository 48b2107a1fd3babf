"""The jog's per-cycle law: a speed target in, the motor counts of this cycle out.

A jog keeps a **reference** that moves at the commanded speed: a gripper pose for a
twist (position and rotation, moved each cycle by the twist and solved back to joint
angles by damped least squares on the closed-form Jacobian, so the reference's path has
no integration drift and a pure x twist is a straight line), joint angles for a joint
jog. It starts from the motor angles the arm is predicted to have when this cycle's
command starts acting, and each cycle it advances by one cycle of motion. The counts are
then those of the default tracking mode (:mod:`services.controller.laws`): the motor
angles at the command's start predicted from the increments in flight through the
drives' lag (:class:`~services.controller.estimator.DriveEstimator`), the dead-beat speed
that lands them on the reference one cycle later
(:func:`~services.controller.estimator.deadbeat_speed`), and the Cartesian-aware
rounding of it (:func:`~services.controller.laws.cartesian_rounding`).

Per cycle, before the step is taken: the commanded speed ramps toward the target
(``*_accel``, one factor for the whole vector so the direction is kept), the step is
scaled down uniformly if a motor would exceed the joint cap, and then shortened near a
singularity or a joint limit (:mod:`.jog_limits`). When the arm cannot follow (held by a
limit, refused by the arm), the reference restarts from the prediction
(``reanchor_deg``) instead of running away.

Drink mode: the angular velocity is a yaw about the base z axis only, so the reference
keeps the gripper's pitch and roll (the cup level) exactly; ``pour`` turns about the
gripper's y axis through the rim point (``rim_offset`` in the gripper frame), so the
rim stays where it is while the cup tilts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from manus.joint_map import dh_to_encoder_list, encoder_to_dh
from manus.kinematics import fk, jacobian_columns
from manus.orientation import rotation_error
from manus.quantize import COUNT_RAD_S, JOINT_COUNT_MAX, saturate_values
from schemas.jog import JogKind, LimitKind
from services.controller.config import ControllerConfig
from services.controller.estimator import DriveEstimator, deadbeat_speed, lag_factor
from services.controller.jog_config import JogConfig
from services.controller.jog_limits import FREE, Slowdown, slowdown
from services.controller.laws import cartesian_rounding, hold_pulses


class JogTarget(NamedTuple):
    """What the user asks for, in SI units, scaled by the speed level and the caps.

    Attributes:
        kind: ``twist`` or ``joints``.
        frame: ``base`` or ``gripper`` (axes of ``linear`` and ``angular``).
        linear: gripper origin velocity [m/s], 3 values.
        angular: angular velocity [rad/s], 3 values (drink mode: only the base yaw, z).
        joints: DH joint velocities [rad/s], 6 values.
        gripper: gripper opening speed [m/s].
        drink: keep the cup level.
        pour: tilt rate about the rim [rad/s].
        caps: the level's caps that scaled the command down (the arm's speeds by one
            factor, the gripper's alone), as the jog state reports them.
    """

    kind: str
    frame: str
    linear: tuple[float, ...]
    angular: tuple[float, ...]
    joints: tuple[float, ...]
    gripper: float
    drink: bool
    pour: float
    caps: tuple[Slowdown, ...] = ()

    @property
    def arm_moves(self) -> bool:
        """Some arm speed is not zero (the gripper aside)."""
        return any(self.linear) or any(self.angular) or any(self.joints) or self.pour != 0.0

    def vector(self) -> np.ndarray:
        """The speeds the ramp acts on: (v, w) of a twist, or the joint rates, shape (6,)
        (a twist's pour is folded into ``w`` by :meth:`JogRun.step`)."""
        if self.kind == JogKind.JOINTS:
            return np.array(self.joints, dtype=float)
        return np.array((*self.linear, *self.angular), dtype=float)


def rodrigues(w: np.ndarray) -> np.ndarray:
    """Rotation matrix of rotation vector ``w`` [rad], shape (3,) -> (3, 3)."""
    angle = float(np.linalg.norm(w))
    if angle < 1e-15:
        return np.eye(3)
    k = w / angle
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.asarray(np.eye(3) + math.sin(angle) * K + (1.0 - math.cos(angle)) * (K @ K))


class StepResult(NamedTuple):
    """One cycle of a jog.

    Attributes:
        q_target: reference DH angles one cycle after the command starts acting [rad].
        limit: the slow-down applied (:data:`~services.controller.jog_limits.FREE`: none).
        reanchored: the reference restarted from the prediction this cycle.
    """

    q_target: list[float]
    limit: Slowdown
    reanchored: bool


@dataclass
class JogRun:
    """The reference of one jog (see the module docstring), from its first cycle.

    Attributes:
        kind, frame, drink: what the reference follows (another kind starts a new run).
        q_ref: reference DH angles when the next command starts acting [rad], 6 values.
        pose: reference gripper pose (4, 4) [m] (twist runs).
        speed: commanded speed after the ramp, shape (6,) (:meth:`JogTarget.vector`).
    """

    kind: str
    frame: str
    drink: bool
    q_ref: list[float]
    pose: np.ndarray
    speed: np.ndarray

    @classmethod
    def start(cls, target: JogTarget, q: list[float], config: ControllerConfig) -> JogRun:
        """A run whose reference starts at DH angles ``q`` [rad]."""
        return cls(target.kind, target.frame, target.drink, q, fk(q, config.arm), np.zeros(6))

    def follows(self, target: JogTarget) -> bool:
        """The run can follow ``target`` (same kind, frame and drink mode)."""
        return (target.kind, target.frame, target.drink) == (self.kind, self.frame, self.drink)

    def step(
        self, target: JogTarget, q_pred: list[float], cfg: JogConfig, config: ControllerConfig
    ) -> StepResult:
        """Advance the reference by one cycle toward ``target``.

        Args:
            target: the speeds asked for.
            q_pred: DH angles predicted at the command's start [rad], 6 values.
            cfg: jog settings.
            config: controller settings (cycle, arm).
        """
        dt = config.cycle_s
        motors_ref = dh_to_encoder_list(self.q_ref)
        motors_pred = dh_to_encoder_list(q_pred)
        gap = max(abs(a - b) for a, b in zip(motors_ref, motors_pred, strict=True))
        reanchored = gap > math.radians(cfg.reanchor_deg)
        if reanchored:
            self.q_ref = list(q_pred)
            self.pose = fk(q_pred, config.arm)
        self._ramp(target.vector(), cfg, dt)
        q0 = self.q_ref
        if self.kind == JogKind.JOINTS:
            q1 = [a + v * dt for a, v in zip(q0, self.speed.tolist(), strict=True)]
            pose1 = self.pose
        else:
            pose1 = self._moved_pose(target.pour, cfg, dt)
            q1 = _solve(q0, pose1, cfg, config)
        step = [b - a for a, b in zip(q0, q1, strict=True)]
        cap = min(cfg.max_joint, *config.arm.max_speed) * dt
        fastest = max(abs(v) for v in dh_increments(step))
        share, limit = 1.0, FREE
        if fastest > cap:
            share = cap / fastest
            words = f"the joint speed cap {math.degrees(cap / dt):.0f} deg/s"
            limit = Slowdown(share, LimitKind.SPEED_CAP, "motors", 0.0, words)
        zone = slowdown(q0, q1, config.arm, cfg)
        if zone.scale < 1.0:
            share, limit = share * zone.scale, zone
        if share < 1.0:
            if self.kind == JogKind.JOINTS:
                q1 = [a + share * d for a, d in zip(q0, step, strict=True)]
            else:  # the same share of the Cartesian step: still on the line
                pose1 = _between(self.pose, pose1, share)
                q1 = _solve(q0, pose1, cfg, config)
                moved = dh_increments([b - a for a, b in zip(q0, q1, strict=True)])
                over = max(abs(v) for v in moved) / cap
                if over > 1.0:  # the solve's own rounding: never above the cap
                    q1 = [a + (b - a) / over for a, b in zip(q0, q1, strict=True)]
            self.speed = self.speed * share
        self.q_ref, self.pose = q1, pose1
        return StepResult(q1, limit, reanchored)

    def _ramp(self, wanted: np.ndarray, cfg: JogConfig, dt: float) -> None:
        change = wanted - self.speed
        if self.kind == JogKind.JOINTS:
            norms = [(float(np.abs(change).max()), cfg.joint_accel * dt)]
        else:
            norms = [
                (float(np.linalg.norm(change[:3])), cfg.linear_accel * dt),
                (float(np.linalg.norm(change[3:])), cfg.angular_accel * dt),
            ]
        share = min([1.0] + [room / size for size, room in norms if size > room])
        self.speed = self.speed + change * share

    def _moved_pose(self, pour: float, cfg: JogConfig, dt: float) -> np.ndarray:
        R, p = self.pose[:3, :3], self.pose[:3, 3]
        v, w = self.speed[:3], self.speed[3:]
        if self.drink:
            w = np.array([0.0, 0.0, w[2]])  # yaw about the base z: pitch and roll kept
            if self.frame == "gripper":
                v = R @ v
        elif self.frame == "gripper":
            v, w = R @ v, R @ w
        if pour != 0.0:  # turn about the rim point first (exactly, not to first order)
            turn = rodrigues(pour * dt * R[:, 1])
            rim = p + R @ np.asarray(cfg.rim_offset)
            R, p = turn @ R, rim + turn @ (p - rim)
        moved = np.eye(4)
        moved[:3, :3] = rodrigues(w * dt) @ R
        moved[:3, 3] = p + v * dt
        return moved


def _between(a: np.ndarray, b: np.ndarray, share: float) -> np.ndarray:
    """The pose ``share`` of the way from pose ``a`` to pose ``b`` (4, 4): position on the
    segment, rotation about the fixed axis between them."""
    out = np.eye(4)
    out[:3, 3] = a[:3, 3] + share * (b[:3, 3] - a[:3, 3])
    out[:3, :3] = rodrigues(share * rotation_error(b[:3, :3], a[:3, :3])) @ a[:3, :3]
    return out


def dh_increments(dq: list[float]) -> list[float]:
    """Motor increments of DH increments (the coupling of joints 2 and 3), 6 values."""
    d1, d2, d3, d4, d5, d6 = dq
    return [d1, -d2, d3 - d2, d4, d5, d6]


def _solve(
    q0: list[float], pose: np.ndarray, cfg: JogConfig, config: ControllerConfig, iterations: int = 2
) -> list[float]:
    """DH angles near ``q0`` [rad] whose gripper pose is ``pose``: Gauss-Newton steps with
    damped least squares (rotation rows weighted by ``rotation_weight_m``)."""
    q = np.array(q0, dtype=float)
    weight = np.array([1.0, 1.0, 1.0] + [cfg.rotation_weight_m] * 3)
    damping = cfg.damping_m**2 * np.eye(6)
    for _ in range(iterations):
        T = fk(q, config.arm)
        err = np.concatenate((pose[:3, 3] - T[:3, 3], rotation_error(pose[:3, :3], T[:3, :3])))
        J = np.array(jacobian_columns(q, config.arm)).T * weight[:, None]
        e = err * weight
        q = q + J.T @ np.linalg.solve(J @ J.T + damping, e)
    return [float(v) for v in q]


def jog_counts(
    q_target: list[float], est: DriveEstimator, config: ControllerConfig, holding: bool = False
) -> np.ndarray:
    """Counts that bring the motors onto ``q_target`` [rad] one cycle after the command
    starts acting: the default mode's delay compensation, dead-beat speed and Cartesian
    rounding (module docstring), shape (6,) int64; ``holding`` (the reference stands
    still: stopped at a limit): the default mode's one-cycle pulses between rests
    (:func:`~services.controller.laws.hold_pulses`), so the arm holds without a limit cycle.

    Raises:
        RuntimeError: the estimator has no reading.
    """
    period = config.cycle_s
    tau = config.drive_tau_ms / 1000.0
    x1, v1 = est.predict(config.command_delay_ms / 1000.0)
    target = dh_to_encoder_list(q_target)
    if holding:
        return hold_pulses(config, x1, v1, target, q_target)
    u = deadbeat_speed(x1, v1, target, period, tau)
    wanted = saturate_values([v / COUNT_RAD_S for v in u], float(JOINT_COUNT_MAX))
    lag = lag_factor(tau, period)
    gain = (period - lag) * COUNT_RAD_S
    miss = [x + v * lag - t for x, v, t in zip(x1, v1, target, strict=True)]
    return cartesian_rounding(wanted, miss, gain, q_target, config)


def predicted_dh(est: DriveEstimator, config: ControllerConfig) -> list[float]:
    """DH angles [rad] predicted when this cycle's command starts acting.

    Raises:
        RuntimeError: the estimator has no reading.
    """
    x1, _ = est.predict(config.command_delay_ms / 1000.0)
    return [float(v) for v in encoder_to_dh(np.array(x1))]


__all__ = [
    "JogRun",
    "JogTarget",
    "StepResult",
    "dh_increments",
    "jog_counts",
    "predicted_dh",
    "rodrigues",
]
