"""The simulated arm's mechanics: motors, belts, joints and gripper, one step at a time.

State lives in motor (encoder) space [deg], because that is what the drives integrate and
what the encoders measure; DH angles come from :mod:`manus.joint_map` (joint 3's DH angle
moves with motor 2: docs/protocol.md, Encoder map). Per step:

1. target motor speeds (already multiplied by each joint's gain error) through the
   first-order lag (:func:`~services.simulator.drives.lag_step`), or, in a fold procedure,
   a constant-speed move toward the fold pose;
2. stuck motors hold;
3. joint limits: a joint stops at its limit (warning 3 while it is pushed against it);
4. work area: a motion that would straighten the elbow further inside the stretched
   margin (warning 2) or take the gripper deeper into the forbidden area (warning 1) is
   refused, the arm holds;
5. gripper (0..max; not below the width of an object held between the jaws), then the
   belts: the true joint follows its motor through a dead band,
   and joint 1 has a scale error;
6. the scene (:mod:`services.simulator.contact`): a motion that would take a body of the
   true arm, or the object it holds (:attr:`ArmModel.held`), deeper into an object (or
   the arm itself) is refused, the arm holds where the body met it (warning 3, "motor
   blocked"), also during a fold.

:meth:`ArmModel.step` is pure, so the core also uses it to evaluate the truth between ticks.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from manus.joint_map import M_ENCODER_TO_DH, dh_to_encoder, encoder_to_dh
from manus.kinematics import fk
from manus.protocol import WARN_MOTOR_BLOCKED, WARN_STRETCHED, WARN_WRONG_AREA
from services.simulator.config import SimConfig
from services.simulator.contact import ContactModel, Distance
from services.simulator.drives import backlash, lag_step, move_toward
from services.simulator.workspace import area_violation, stretch_violation

Measure = Callable[[np.ndarray, float], Distance | None]
"""The smallest true distance of something the arm carries, at DH angles [deg] and a
gripper opening [mm] (None: nothing to measure)."""

_DQ_DE = np.diag(M_ENCODER_TO_DH).copy()
"""d q_i / d e_i: how DH joint i moves with its own motor (the diagonal of the map)."""
_EPS = 1e-9


def motor_to_dh_deg(e_deg: np.ndarray) -> np.ndarray:
    """DH joint angles [deg] from motor angles [deg], shape (6,)."""
    return np.asarray(np.degrees(encoder_to_dh(np.radians(e_deg))))


def dh_to_motor_deg(q_deg: np.ndarray) -> np.ndarray:
    """Motor angles [deg] from DH joint angles [deg], shape (6,)."""
    return np.asarray(np.degrees(dh_to_encoder(np.radians(q_deg))))


@dataclass(frozen=True)
class ArmState:
    """The mechanical state (arrays are never modified in place).

    Attributes:
        motor_deg: motor (encoder) angles e1..e6, shape (6,) [deg].
        speed_deg_s: motor speeds, shape (6,) [deg/s].
        output_deg: belt output side of each motor (after backlash), shape (6,) [deg].
        gripper_mm: gripper opening [mm].
        gripper_speed_mm_s: gripper opening speed [mm/s].
    """

    motor_deg: np.ndarray
    speed_deg_s: np.ndarray
    output_deg: np.ndarray
    gripper_mm: float
    gripper_speed_mm_s: float


@dataclass(frozen=True)
class Intent:
    """What the drives are asked to do over one step.

    Attributes:
        rates_deg_s: target motor speeds (gain error not applied yet), shape (6,)
            [deg/s]; for a fold, the constant speed magnitude of each motor.
        gripper_mm_s: target gripper speed [mm/s].
        fold_target_deg: motor angles a fold procedure drives to (None: no fold). A fold
            moves at exactly ``rates_deg_s`` (no lag) and stops dead on arrival or when its
            rates are zero (paused).
        stuck: motors that cannot move, shape (6,) of bool.
        checks: refuse motion into the stretched elbow or the forbidden area.
        gripper_min_mm: the jaws cannot close below this (an object held between them)
            [mm].
    """

    rates_deg_s: np.ndarray
    gripper_mm_s: float = 0.0
    fold_target_deg: np.ndarray | None = None
    stuck: np.ndarray | None = None
    checks: bool = True
    gripper_min_mm: float = 0.0


class StepResult(NamedTuple):
    """The outcome of one step.

    Attributes:
        state: the state at the end of the step.
        warnings: warning codes raised during the step.
        arrived: a fold procedure reached its target.
        distance: smallest true distance to the scene at the end [m] (None: no scene).
        contact: ``body/object`` that met and stopped the arm ("" : none).
    """

    state: ArmState
    warnings: frozenset[int]
    arrived: bool
    distance: Distance | None = None
    contact: str = ""


class ArmModel:
    """The arm's mechanics for one configuration.

    Args:
        config: the simulator configuration.
        gains: per-motor speed gains (1 + error), shape (6,) [-].
    """

    def __init__(self, config: SimConfig, gains: np.ndarray) -> None:
        self.config = config
        self.gains = np.asarray(gains, dtype=float)
        self.tau_s = config.transient_tau_ms / 1000.0
        self.width = np.asarray(config.backlash_deg, dtype=float)
        self.lower_deg = np.degrees(config.arm.lower_array)
        self.upper_deg = np.degrees(config.arm.upper_array)
        self.gripper_max_mm = config.arm.gripper_max * 1000.0
        # The arm's own work area (warnings 1 and 2): the arm's, as the planner keeps it.
        self.stretched_margin_deg = math.degrees(config.arm.stretched_margin)
        self.floor_z_mm = config.arm.work_floor_z * 1000.0
        self.radius_mm = config.arm.work_base_radius * 1000.0
        self._area_cache: dict[bytes, float] = {}
        # The power-up measurement of absolute angles is right; the scale error of joint 1's
        # transmission accumulates with its motion from there.
        self._q1_start = float(config.start_q_deg[0])
        self.contacts = ContactModel(config.scene, config.arm, config.start_gripper_mm * 1e-3)
        self.held: Measure | None = None
        """The held object's smallest true distance to the scene at DH angles [deg] and a
        gripper opening [mm] (None: nothing to hold; set by the simulator's objects,
        :mod:`services.simulator.object_world`): it meets the scene as a body does, but
        for :attr:`held_touch`."""
        self.held_touch = 0.0
        """How deep the held object may touch the scene [m] before the arm is blocked (set
        with :attr:`held`: the objects' contact depth). A cup standing on the table when
        the jaws close on it touches it; the arm's lag (the drives' speed decays, never
        quite reaching zero) then took it nanometres into the table, which blocked the arm
        for a tick as a push into the table would (a one-tick ``cup/table`` contact, seen
        under load when the jaws closed soon after the arm's last correction)."""

    def initial_state(self) -> ArmState:
        """At rest in the configured start pose, every belt's slack centred."""
        e = dh_to_motor_deg(np.asarray(self.config.start_q_deg, dtype=float))
        return ArmState(e, np.zeros(6), e.copy(), self.config.start_gripper_mm, 0.0)

    def q_true_deg(self, state: ArmState) -> np.ndarray:
        """True DH joint angles [deg]: belt outputs; joint 1 moves (1 + scale error) times
        its motor's motion from the start pose."""
        q = motor_to_dh_deg(state.output_deg)
        q[0] = self._q1_start + (q[0] - self._q1_start) * (1.0 + self.config.joint1_scale_error)
        return q

    def gripper_xyz_mm(self, q_deg: np.ndarray) -> np.ndarray:
        """Gripper position in the base frame [mm] for DH angles [deg], shape (3,)."""
        return np.asarray(fk(np.radians(q_deg), self.config.arm)[:3, 3] * 1000.0)

    def step(self, state: ArmState, intent: Intent, dt_s: float) -> StepResult:
        """Advance the mechanics by ``dt_s`` [s] (pure)."""
        warnings: set[int] = set()
        x0 = state.motor_deg
        if intent.fold_target_deg is not None:
            target = intent.fold_target_deg
            x, v = move_toward(x0, target, intent.rates_deg_s, dt_s)
            v = np.where(np.abs(target - x) <= _EPS, 0.0, v)  # arrived: stopped
            pushing = (np.abs(target - x0) > _EPS) & (intent.rates_deg_s > 0.0)
        else:
            u = intent.rates_deg_s * self.gains
            x, v = lag_step(x0, state.speed_deg_s, u, dt_s, self.tau_s)
            pushing = np.abs(u) > 0.0
        if intent.stuck is not None and intent.stuck.any():
            if np.any(pushing & intent.stuck):
                warnings.add(WARN_MOTOR_BLOCKED)
            x = np.where(intent.stuck, x0, x)
            v = np.where(intent.stuck, 0.0, v)
        x, v, blocked = self._limit(x, v)
        if blocked:
            warnings.add(WARN_MOTOR_BLOCKED)
        if intent.checks and not np.array_equal(x, x0):
            refused = self._refusal(x0, x)
            if refused is not None:
                warnings.add(refused)
                x, v = x0, np.zeros(6)
        g, gv = self._gripper(state, intent.gripper_mm_s, dt_s, intent.gripper_min_mm)
        out = backlash(state.output_deg, x, self.width)
        end = ArmState(x, v, out, g, gv)
        q_end = self.q_true_deg(end)
        after = self.contacts.distance(q_end, g)
        contact = ""
        if not np.array_equal(x, x0):
            contact = self._meets(self.contacts.distance, state, q_end, g, after)
            if not contact and self.held is not None:
                contact = self._meets(self.held, state, q_end, g, touch=self.held_touch)
            if contact:
                warnings.add(WARN_MOTOR_BLOCKED)
                end = ArmState(x0, np.zeros(6), state.output_deg, g, gv)
                x = x0
                after = self.contacts.distance(self.q_true_deg(state), state.gripper_mm)
        arrived = intent.fold_target_deg is not None and bool(
            np.all(np.abs(intent.fold_target_deg - x) <= _EPS)
        )
        return StepResult(end, frozenset(warnings), arrived, after, contact)

    def _meets(
        self,
        measure: Measure,
        state: ArmState,
        q_end: np.ndarray,
        gripper_mm: float,
        after: Distance | None = None,
        touch: float = 0.0,
    ) -> str:
        """``body/object`` when the step from ``state`` to true DH angles ``q_end`` [deg]
        and opening ``gripper_mm`` [mm] takes that pair deeper into contact, past
        ``touch`` [m] of penetration ('': it does not)."""
        if after is None:
            after = measure(q_end, gripper_mm)
        if after is None or after.distance >= -touch:
            return ""
        before = measure(self.q_true_deg(state), state.gripper_mm)
        return after.pair if before is None or after.distance < before.distance - _EPS else ""

    def _limit(self, x: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray, bool]:
        # Each DH joint i is set by its own motor i (joint 3 relative to motor 2), so clamp
        # in joint order with motor i; q3 is recomputed once motor 2 is final.
        q = motor_to_dh_deg(x)
        if np.all((q >= self.lower_deg) & (q <= self.upper_deg)):
            return x, v, False
        x, v = x.copy(), v.copy()
        blocked = False
        for i in range(6):
            if i == 2:
                q = motor_to_dh_deg(x)
            excess = max(q[i] - self.upper_deg[i], 0.0) + min(q[i] - self.lower_deg[i], 0.0)
            if excess != 0.0:
                x[i] -= excess * _DQ_DE[i]
                v[i] = 0.0
                blocked = blocked or abs(excess) > _EPS
        return x, v, blocked

    def _refusal(self, x0: np.ndarray, x: np.ndarray) -> int | None:
        q0, q1 = motor_to_dh_deg(x0), motor_to_dh_deg(x)
        margin = self.stretched_margin_deg
        if stretch_violation(q1, margin) > stretch_violation(q0, margin) + _EPS:
            return WARN_STRETCHED
        if self._area(x, q1) > self._area(x0, q0) + _EPS:
            return WARN_WRONG_AREA
        return None

    def _area(self, x: np.ndarray, q_deg: np.ndarray) -> float:
        # One forward kinematics per tick: the start of a step is the end of the last one.
        key = x.tobytes()
        cached = self._area_cache.get(key)
        if cached is None:
            cached = area_violation(self.gripper_xyz_mm(q_deg), self.floor_z_mm, self.radius_mm)
            if len(self._area_cache) >= 4:
                self._area_cache.clear()
            self._area_cache[key] = cached
        return cached

    def _gripper(
        self, state: ArmState, rate_mm_s: float, dt_s: float, lowest_mm: float
    ) -> tuple[float, float]:
        gx, gv = lag_step(
            np.array([state.gripper_mm]),
            np.array([state.gripper_speed_mm_s]),
            np.array([rate_mm_s]),
            dt_s,
            self.tau_s,
        )
        g, speed = float(gx[0]), float(gv[0])
        lowest = min(max(lowest_mm, 0.0), self.gripper_max_mm)
        if g <= lowest or g >= self.gripper_max_mm:
            return min(max(g, lowest), self.gripper_max_mm), 0.0
        return g, speed


def fold_rates(x0: np.ndarray, target: np.ndarray, speed_deg_s: float) -> np.ndarray:
    """Constant motor speeds [deg/s] so that every motor reaches ``target`` together.

    The motor with the longest way moves at ``speed_deg_s``; shape (6,).
    """
    way = np.abs(target - x0)
    longest = float(way.max())
    if longest <= 0.0 or not math.isfinite(longest):
        return np.zeros(6)
    return np.asarray(way * (speed_deg_s / longest))
