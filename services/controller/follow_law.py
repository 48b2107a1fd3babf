"""The follow goal's per-cycle law: a predicted target in, this cycle's joint target out.

Like the jog (:mod:`.jog_law`), a follow goal keeps a **reference**: the tracked point
(the gripper's origin, or a held object's point ``offset`` in the gripper frame) with the
gripper's orientation held as it was when the goal started. The reference starts from
the motor angles the arm is predicted to have when this cycle's command starts acting;
each cycle it moves by one cycle of motion toward the **standoff point**: the target
predicted to the end of that cycle (:mod:`.target_track`), ``standoff`` out along the
approach axis, and pushed further out until it keeps the person's clearance (a goal's
``close_clearance`` in the closer approach). The joint angles come from one damped
Gauss-Newton step of the closed-form kinematics from the reference's own angles (exact to
the second order of a cycle's motion, without drift).

The velocity of the reference: the target's predicted velocity plus what is left of the
error to the standoff point over one cycle (dead-beat: it lands there), that part, while
it is more than ``lock_m``, capped by the **speed profile** (but for backing away from
the target along the approach axis, never slowed): ``approach_speed``, slowing
inside ``slow_radius_m`` of the standoff point and on the braking curve sqrt(2 accel d),
and near a person (inside ``person_slow_m`` of the clearance), the least of the three;
the whole by ``max_speed`` and by ``accel`` per cycle; in the closer approach, inside
100 mm of the target, by 25 mm/s but for motion away from it. Then, as for a jog, the
step is scaled down whole if a motor would exceed the joint cap, and shortened near the
wrist and elbow singularities and the joint limits (:mod:`.jog_limits`). A reference
inside the person's clearance (the person leaned in faster than the arm backed off) only
backs away along the approach axis, never closer. The counts:
:func:`follow_counts` (the jog's, with the belts' play compensated when it is set).

Faults (the source stops and ends the goal): the standoff point out of reach or in a
keep-out zone; the way to it stopped at the wrist singularity (``singularity``), at the
stretched elbow or a joint limit (``out_of_reach``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from manus.joint_map import dh_to_encoder_list
from manus.kinematics import Rot, Vec3, gripper_pose, jacobian_columns
from manus.quantize import COUNT_RAD_S, JOINT_COUNT_MAX, saturate_values
from schemas.control import EndCause
from schemas.follow import CLOSE_SPEED_CAP, CLOSE_ZONE
from schemas.jog import LimitKind
from services.controller.backlash import PlayModel
from services.controller.config import ControllerConfig
from services.controller.estimator import DriveEstimator, deadbeat_speed, lag_factor
from services.controller.follow_config import FollowConfig
from services.controller.follow_space import FollowSpace
from services.controller.jog_law import dh_increments
from services.controller.jog_limits import FREE, Slowdown, slowdown
from services.controller.laws import cartesian_rounding, hold_pulses


class Settings(NamedTuple):
    """A follow goal's settings, resolved against the controller's.

    Attributes:
        standoff: from the target along the approach axis [m].
        approach: the approach axis in the target's frame, unit length.
        offset: the tracked point in the gripper frame [m].
        max_speed: speed cap of the tracked point [m/s].
        clearance: the tracked point's smallest distance to a person [m].
        close: the closer approach (its speed cap inside 100 mm of the target).
        lean_s: the standoff grows by the target's speed toward the arm times this [s].
    """

    standoff: float
    approach: Vec3
    offset: Vec3
    max_speed: float
    clearance: float
    close: bool
    lean_s: float = 0.0


class Aim(NamedTuple):
    """Where the target will be when this cycle's command ends, in the base frame.

    Attributes:
        target: the target point [m].
        velocity: its velocity [m/s].
        normal: the approach axis [-], unit length.
    """

    target: Vec3
    velocity: Vec3
    normal: Vec3


class Fault(NamedTuple):
    """Why the goal must stop.

    Attributes:
        cause: the kind.
        reason: in words.
    """

    cause: EndCause
    reason: str


class FollowStep(NamedTuple):
    """One cycle of a follow goal.

    Attributes:
        q_target: the reference's DH angles one cycle after the command starts acting [rad].
        point: the reference's tracked point then [m].
        aim: the standoff point [m].
        distance: from the reference's tracked point to the standoff point [m].
        speed_cap: the cap on the tracked point's speed this cycle [m/s].
        limits: what held the step back (speed caps, zones).
        fault: why the goal must stop (None: it need not).
        still: the reference did not move (hold without a limit cycle).
    """

    q_target: list[float]
    point: Vec3
    aim: Vec3
    distance: float
    speed_cap: float
    limits: tuple[Slowdown, ...]
    fault: Fault | None = None
    still: bool = False


def _add(a: Vec3, b: Vec3, k: float = 1.0) -> Vec3:
    return a[0] + k * b[0], a[1] + k * b[1], a[2] + k * b[2]


def _sub(a: Vec3, b: Vec3) -> Vec3:
    return a[0] - b[0], a[1] - b[1], a[2] - b[2]


def _norm(a: Vec3) -> float:
    return math.sqrt(a[0] * a[0] + a[1] * a[1] + a[2] * a[2])


def _rot(R: Rot, v: Vec3) -> Vec3:
    return (
        R[0] * v[0] + R[1] * v[1] + R[2] * v[2],
        R[3] * v[0] + R[4] * v[1] + R[5] * v[2],
        R[6] * v[0] + R[7] * v[1] + R[8] * v[2],
    )


def _capped(v: Vec3, cap: float) -> Vec3:
    size = _norm(v)
    return (
        v
        if size <= cap or size == 0.0
        else (v[0] * cap / size, v[1] * cap / size, v[2] * cap / size)
    )


def standoff_point(settings: Settings, aim: Aim, space: FollowSpace) -> Vec3:
    """The target, ``standoff`` (grown while the target comes at the arm) out along the
    approach axis, pushed further out until it keeps the clearance from every person [m]."""
    n, v = aim.normal, aim.velocity
    coming = max(0.0, v[0] * n[0] + v[1] * n[1] + v[2] * n[2])
    point = _add(aim.target, n, settings.standoff + settings.lean_s * coming)
    for _ in range(10):  # one push along the normal; more along an axis near the tangent
        distance, _name = space.person_distance(point)
        short = settings.clearance - distance
        if short <= 0.0:
            break
        point = _add(point, aim.normal, short + 1e-4)
    return point


_DIAG = np.diag_indices(6)
CLOSE_SHARE = 0.7
"""The reference's share of the closer approach's speed cap: a joint's speeds come in
5 deg/s steps, so the arm's speed over one cycle dithers about the command by up to
10 mm/s here, and it catches up with the reference after a sway; at 70 % its speed over
0.3 s stays below the cap."""
CLOSE_LEAD = 0.030
"""The reference slows this much before the closer approach's zone [m]: it leads the arm
by up to two cycles, so the arm itself is at the capped speed when it enters."""


@dataclass
class FollowRun:
    """The reference of one follow goal (see the module docstring).

    Attributes:
        settings: the goal's settings.
        q_ref: the reference's DH angles when the next command starts acting [rad].
        rotation: the gripper orientation held (row by row).
        point: the reference's tracked point [m].
        velocity: the reference's velocity over the last cycle [m/s].
    """

    settings: Settings
    q_ref: list[float]
    rotation: Rot
    point: Vec3
    velocity: Vec3 = (0.0, 0.0, 0.0)

    @classmethod
    def start(cls, settings: Settings, q: list[float], config: ControllerConfig) -> FollowRun:
        """A run whose reference starts at DH angles ``q`` [rad]."""
        p, R = gripper_pose(q, config.arm)
        return cls(settings, list(q), R, _add(p, _rot(R, settings.offset)))

    def anchor(self, q_pred: list[float], config: ControllerConfig) -> bool:
        """Restart the reference from the prediction when the arm was held back (more than
        ``reanchor_deg`` on a motor); True when it did."""
        ref = dh_to_encoder_list(self.q_ref)
        pred = dh_to_encoder_list(q_pred)
        if max(abs(a - b) for a, b in zip(ref, pred, strict=True)) <= math.radians(
            config.jog.reanchor_deg
        ):
            return False
        p, _ = gripper_pose(q_pred, config.arm)
        self.q_ref = list(q_pred)
        self.point = _add(p, _rot(self.rotation, self.settings.offset))
        self.velocity = (0.0, 0.0, 0.0)
        return True

    def check(self, standoff: Vec3, space: FollowSpace, config: ControllerConfig) -> Fault | None:
        """Whether the standoff point can be reached at all (zones, reach)."""
        zone = space.zone_breach(standoff)
        if zone is not None:
            return Fault(EndCause.KEEP_OUT, f"the standoff point is {zone}")
        gripper = _sub(standoff, _rot(self.rotation, self.settings.offset))
        wrist = _sub(gripper, _rot(self.rotation, (0.0, 0.0, config.arm.l4)))
        far = space.reach_breach(wrist, config.follow.reach_margin_deg)
        if far is not None:
            return Fault(EndCause.OUT_OF_REACH, f"the standoff point is out of reach: {far}")
        return None

    def step(self, aim: Aim, space: FollowSpace, config: ControllerConfig) -> FollowStep:
        """Advance the reference by one cycle toward the standoff point of ``aim``."""
        s, cfg, dt = self.settings, config.follow, config.cycle_s
        goal = standoff_point(s, aim, space)
        fault = self.check(goal, space, config)
        error = _sub(goal, self.point)
        d = _norm(error)
        if fault is not None:
            return FollowStep(list(self.q_ref), self.point, goal, d, 0.0, (), fault)
        cap, limits = self._profile(d, space, cfg)
        # the error at the end of the cycle if the reference moved with the target
        rel = _sub((error[0] / dt, error[1] / dt, error[2] / dt), aim.velocity)
        if _norm(rel) * dt > cfg.lock_m:  # closing in: the profile; locked on: dead-beat
            n = aim.normal  # backing away from the target is never slowed
            out = max(0.0, rel[0] * n[0] + rel[1] * n[1] + rel[2] * n[2])
            rel = _add(_capped(_sub(rel, (n[0] * out, n[1] * out, n[2] * out)), cap), n, out)
        v = _add(aim.velocity, rel)
        v = _capped(v, s.max_speed)
        if s.close:
            v = self._close_cap(v, aim.target)
        change = _capped(_sub(v, self.velocity), cfg.accel * dt)
        v = _add(self.velocity, change)
        q0 = self.q_ref
        point1 = _add(self.point, v, dt)
        near, _ = space.person_distance(point1)
        if near < s.clearance and near < space.person_distance(self.point)[0]:
            # inside the person's clearance (the person came in): only backing away
            n = aim.normal
            out = max(0.0, v[0] * n[0] + v[1] * n[1] + v[2] * n[2])
            v = (n[0] * out, n[1] * out, n[2] * out)
            point1 = _add(self.point, v, dt)
        q1 = self._solve(q0, point1, config)
        step = [b - a for a, b in zip(q0, q1, strict=True)]
        share, limit = 1.0, FREE
        top = min(config.jog.max_joint, *config.arm.max_speed) * dt
        fastest = max(abs(x) for x in dh_increments(step))
        if fastest > top:
            share = top / fastest
            limit = Slowdown(share, LimitKind.SPEED_CAP, "motors", 0.0, "the joint speed cap")
        zone = slowdown(q0, q1, config.arm, config.jog)
        if zone.scale <= 0.0 and d > cfg.hold_tolerance_m:
            return FollowStep(list(q0), self.point, goal, d, cap, (zone,), _zone_fault(zone))
        if zone.scale < 1.0:
            share, limit = share * zone.scale, zone
        if share < 1.0:
            v = (v[0] * share, v[1] * share, v[2] * share)
            point1 = _add(self.point, v, dt)
            q1 = self._solve(q0, point1, config)
            limits = (*limits, limit)
        still = _norm(v) * dt < 1e-5
        self.q_ref, self.point, self.velocity = q1, point1, v
        return FollowStep(q1, point1, goal, _norm(_sub(goal, point1)), cap, limits, None, still)

    def _profile(
        self, d: float, space: FollowSpace, cfg: FollowConfig
    ) -> tuple[float, tuple[Slowdown, ...]]:
        """The cap on the speed relative to the target [m/s] at ``d`` from the standoff
        point, and what set it."""
        s = self.settings
        cap = cfg.approach_speed
        limits: list[Slowdown] = []
        if cfg.slow_radius_m > 0.0 and d < cfg.slow_radius_m:
            cap *= max(cfg.slow_floor, d / cfg.slow_radius_m)
        cap = min(cap, math.sqrt(2.0 * cfg.accel * d))
        near, name = space.person_distance(self.point)
        room = near - s.clearance
        if name and cfg.person_slow_m > 0.0 and room < cfg.person_slow_m:
            share = max(cfg.person_floor, room / cfg.person_slow_m)
            cap = min(cap, cfg.approach_speed * share)
            words = f"near the person ({name})"
            limits.append(
                Slowdown(share, LimitKind.COLLISION, name, 0.0, words, "tracked point", near)
            )
        return cap, tuple(limits)

    def _close_cap(self, v: Vec3, target: Vec3) -> Vec3:
        """The closer approach inside 100 mm of the target (the reference from
        :data:`CLOSE_LEAD` before): at most 25 mm/s but for motion away from it."""
        away = _sub(self.point, target)
        size = _norm(away)
        if size >= CLOSE_ZONE + CLOSE_LEAD or size == 0.0:
            return v
        u = (away[0] / size, away[1] / size, away[2] / size)
        along = v[0] * u[0] + v[1] * u[1] + v[2] * u[2]
        out = max(along, 0.0)
        rest = _sub(v, (u[0] * out, u[1] * out, u[2] * out))
        return _add(_capped(rest, CLOSE_SPEED_CAP * CLOSE_SHARE), u, out)

    def _solve(self, q0: list[float], point: Vec3, config: ControllerConfig) -> list[float]:
        """DH angles near ``q0`` [rad] whose tracked point is ``point`` with the held
        orientation: one damped Gauss-Newton step (rotation rows weighted by the jog's
        ``rotation_weight_m``)."""
        R = self.rotation
        p, Rq = gripper_pose(q0, config.arm)
        tip = _add(p, _rot(Rq, self.settings.offset))
        w = config.jog.rotation_weight_m
        e = [point[0] - tip[0], point[1] - tip[1], point[2] - tip[2], *_rot_error(R, Rq, w)]
        cols = jacobian_columns(q0, config.arm)
        off = _rot(Rq, self.settings.offset)  # the tracked point moves with the gripper's turn
        J = np.empty((6, 6))
        for j, (a, b, c, x, y, z) in enumerate(cols):
            J[:, j] = (
                a + y * off[2] - z * off[1],
                b + z * off[0] - x * off[2],
                c + x * off[1] - y * off[0],
                x * w,
                y * w,
                z * w,
            )
        damped = J @ J.T
        damped[_DIAG] += config.jog.damping_m**2
        dq = J.T @ np.linalg.solve(damped, np.array(e))
        return [a + float(b) for a, b in zip(q0, dq, strict=True)]


def _rot_error(R: Rot, Rq: Rot, weight: float) -> tuple[float, float, float]:
    """The rotation vector from ``Rq`` to ``R`` to first order (the vee of the skew part of
    R Rq^T), times ``weight`` [m]."""

    # E = R Rq^T; rows of R dotted with rows of Rq
    def e(i: int, j: int) -> float:
        return R[3 * i] * Rq[3 * j] + R[3 * i + 1] * Rq[3 * j + 1] + R[3 * i + 2] * Rq[3 * j + 2]

    k = 0.5 * weight
    return k * (e(2, 1) - e(1, 2)), k * (e(0, 2) - e(2, 0)), k * (e(1, 0) - e(0, 1))


def _zone_fault(zone: Slowdown) -> Fault:
    """The fault of a step stopped at a zone: the wrist singularity, or the reach."""
    if zone.object == "wrist":
        return Fault(EndCause.SINGULARITY, f"the way to the standoff point is behind {zone.words}")
    return Fault(EndCause.OUT_OF_REACH, f"the standoff point is beyond {zone.words}")


def follow_counts(
    q_target: list[float],
    est: DriveEstimator,
    play: PlayModel,
    config: ControllerConfig,
    holding: bool = False,
) -> np.ndarray:
    """Counts that bring the joints onto ``q_target`` [rad] one cycle after the command
    starts acting, shape (6,) int64: :func:`~.jog_law.jog_counts` (the default mode's
    delay compensation, dead-beat speed, Cartesian rounding; ``holding``: its pulses
    between rests), with the belts' play compensated as the default mode does when
    ``backlash_deg`` is set (the motors aim past the joints' target by the play).

    Raises:
        RuntimeError: the estimator has no reading.
    """
    period = config.cycle_s
    tau = config.drive_tau_ms / 1000.0
    x1, v1 = est.predict(config.command_delay_ms / 1000.0)
    target = dh_to_encoder_list(q_target)
    if play.active:
        target = play.motor_target(np.array(target), np.array(x1)).tolist()
    if holding:
        return hold_pulses(config, x1, v1, target, q_target)
    u = deadbeat_speed(x1, v1, target, period, tau)
    wanted = saturate_values([v / COUNT_RAD_S for v in u], float(JOINT_COUNT_MAX))
    lag = lag_factor(tau, period)
    gain = (period - lag) * COUNT_RAD_S
    miss = [x + v * lag - t for x, v, t in zip(x1, v1, target, strict=True)]
    return cartesian_rounding(wanted, miss, gain, q_target, config)
