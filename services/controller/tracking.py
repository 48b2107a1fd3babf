"""One trajectory goal being executed: time base, control law, via-point errors, verdicts.

Two control laws (``TrajectoryGoal.mode``; each a :class:`ControlLaw`, the seam a run
calls, implemented in :mod:`.modes` (:data:`.modes.LAWS`), the arithmetic in :mod:`.laws`):

- ``default``, built for the arm's interface. One global time base: trajectory time 0 is
  the moment the first command acts (the start snapshot + ``command_delay_ms``). The
  command computed from the snapshot at s acts during [s+60, s+120) ms, while the one
  sent before it (``JointState.applied_velocity``) acts during [s, s+60): so the motor angles at
  s+60 are predicted from the estimate at s and the increments in flight, through the
  drives' speed lag, and the command is the constant speed that brings them onto the
  reference at s+120 (a dead-beat law in motor space). Its rounding error is not lost:
  the next cycle predicts from the increments actually applied, so the mean speed is
  exact and there is no limit cycle wider than one rounding step.
- ``thesis``, the thesis's loop with its sign corrected (docs/protocol.md): qdot = qdot_ref +
  K (q_ref - q) from the snapshot, uniform saturation, rounding; per-segment timing (a
  segment ends when the gripper is within ``thesis_via_threshold_m`` of its via point or
  its time is over, and the next one restarts from its first knot); after the last via
  point, local rest-to-rest quintics from the measured angles to the last knot until the
  position error is under ``position_tolerance`` (the thesis re-planned; the core cannot
  call the planner, so it re-plans in joint space itself).

Via-point errors (``GoalResult.via_errors``) are measured as the thesis did: the distance
between the forward kinematics of the measured (encoder) angles and the knot's via point,
at the knot's time: in the default mode the measurement is interpolated between the two
snapshots around the knot time, in the thesis mode it is the one at which the segment
ends.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from manus.kinematics import Vec3
from manus.quantize import COUNT_RAD_S, Quantizer
from schemas.control import EndCause, ResultStatus, TrajectoryGoal
from services.controller.backlash import PlayModel
from services.controller.command_source import End
from services.controller.config import ControllerConfig
from services.controller.estimator import DriveEstimator
from services.controller.goals import violation
from services.controller.laws import make_quantizer
from services.controller.reference import Reference, rest_to_rest


class ControlLaw(Protocol):
    """What a control mode decides for a running trajectory goal (:mod:`.modes`: the
    module docstring there). The run keeps the state; a law holds none."""

    def start_tau(self, run: TrajectoryRun) -> float:
        """Trajectory time at the goal's first snapshot [s]."""
        ...

    def tau_at_command(self, run: TrajectoryRun) -> float:
        """Trajectory time when the command computed now starts acting [s]."""
        ...

    def end_tau(self, run: TrajectoryRun) -> float:
        """Trajectory time at which the reference has ended [s]."""
        ...

    def segment(self, run: TrajectoryRun) -> int:
        """Index of the knot interval being tracked."""
        ...

    def measure(self, run: TrajectoryRun, snap_ns: int, q: np.ndarray, xyz: Vec3) -> None:
        """Record the via-point errors due by this snapshot (``run.via_errors``)."""
        ...

    def cycle(
        self,
        run: TrajectoryRun,
        snap_ns: int,
        q: np.ndarray,
        xyz: Vec3,
        est: DriveEstimator,
        play: PlayModel | None,
    ) -> tuple[np.ndarray, End | None]:
        """This cycle's counts, shape (6,) int64, and the end once the reference has
        ended (``run.end_ns`` set) and the goal is judged (None: not yet)."""
        ...

    def unsettled(self, run: TrajectoryRun, q: np.ndarray) -> End | None:
        """The end was not reached yet and time is left: what to do (None: wait)."""
        ...


@dataclass(slots=True)
class Step:
    """The outcome of one cycle of a goal.

    Attributes:
        counts: motor increments to send, shape (6,) int.
        reference: the reference positions at the snapshot [rad], 6 values.
        segment: knot interval being tracked (-1: none).
        state: tracking, settling, decelerating or holding.
        ended: how the goal ended this cycle, else None.
    """

    counts: np.ndarray
    reference: list[float]
    segment: int
    state: str
    ended: End | None = None


@dataclass
class TrajectoryRun:
    """State of one running trajectory goal (see the module docstring).

    Attributes:
        goal: the goal.
        ref: what it follows (a splice's blend included).
        config: controller settings.
        path_tol: per-joint path tolerance [rad] (0: unchecked), shape (6,).
        goal_tol: per-joint goal tolerance [rad] (0: unchecked), shape (6,).
        start_ns: snapshot time of its first cycle [ns].
        scale: speed scale in use.
        scale_target: speed scale asked for (reached at ``speed_scale_rate``).
        tau: trajectory time at the last snapshot [s].
        path_checked: some joint has a path tolerance (checked every cycle).
    """

    goal: TrajectoryGoal
    ref: Reference
    config: ControllerConfig
    law: ControlLaw
    path_tol: np.ndarray
    goal_tol: np.ndarray
    start_ns: int
    scale: float
    scale_target: float
    quantizer: Quantizer
    tau: float = 0.0
    last_ns: int = 0
    segment: int = 0
    via_errors: list[float] = field(default_factory=list)
    via_stamps: list[int] = field(default_factory=list)
    prev: tuple[float, np.ndarray, int] | None = None
    end_ns: int | None = None
    settle: Reference | None = None
    settle_tau: float = 0.0
    settles: int = 0
    cancelling: bool = False
    final_error: float = 0.0
    path_checked: bool = False

    @classmethod
    def start(
        cls,
        goal: TrajectoryGoal,
        ref: Reference,
        config: ControllerConfig,
        tols: tuple[np.ndarray, np.ndarray],
        snap_ns: int,
        scale: float,
        law: ControlLaw,
    ) -> TrajectoryRun:
        """A run whose first cycle is the snapshot at ``snap_ns`` [ns], following
        ``law`` (the goal's mode: :data:`.modes.LAWS`)."""
        quantizer = make_quantizer(config.default_quantizer)
        run = cls(
            goal, ref, config, law, tols[0], tols[1], snap_ns, scale, goal.speed_scale, quantizer
        )
        run.last_ns = snap_ns
        run.path_checked = bool(run.path_tol.any())
        run.tau = law.start_tau(run)
        return run

    def tau_at_command(self) -> float:
        """Trajectory time when the command computed now starts acting [s]."""
        return self.law.tau_at_command(self)

    def current_reference(self) -> tuple[Reference, float]:
        """The reference being followed now and its time when the next command acts."""
        if self.settle is not None:
            return self.settle, self.settle_tau
        return self.ref, self.tau_at_command()

    def reference_at(self, snap_ns: int) -> tuple[Reference, float]:
        """Like :meth:`current_reference` for the command answering the snapshot at
        ``snap_ns`` [ns], before this run has stepped to it (a splice decides there)."""
        ref, tau = self.current_reference()
        return ref, tau + self.scale * (snap_ns - self.last_ns) / 1e9

    def pause(self, snap_ns: int) -> None:
        """The joint states stopped until ``snap_ns`` [ns]: the time base does not advance
        over the gap (the arm was stopped), so the reference resumes where it was, from
        rest: its speed scale ramps back up at ``speed_scale_rate``."""
        self.last_ns = snap_ns
        self.scale = 0.0

    # -- one cycle -----------------------------------------------------------------------

    def step(
        self,
        snap_ns: int,
        q: np.ndarray,
        xyz: Vec3,
        est: DriveEstimator,
        last_counts: np.ndarray,
        play: PlayModel | None = None,
    ) -> Step:
        """Advance to the snapshot at ``snap_ns`` with measured DH angles ``q`` [rad] and
        their gripper position ``xyz`` [m]."""
        dt = (snap_ns - self.last_ns) / 1e9
        self.last_ns = snap_ns
        self.tau += self.scale * dt
        if self.settle is not None:
            self.settle_tau += self.scale * dt
        rate = self.config.speed_scale_rate * dt
        self.scale += min(rate, max(-rate, self.scale_target - self.scale))
        if self.cancelling:
            return self._decelerate(last_counts)
        self.law.measure(self, snap_ns, q, xyz)
        ref = self.ref.position(self.tau)
        moving = self.end_ns is None
        if moving:
            broken = (
                violation(np.subtract(ref, q), self.path_tol, "path") if self.path_checked else None
            )
            if broken is not None:
                return self._abort(ref, f"{broken} at t = {self.tau:.2f} s")
            if self.tau >= self.law.end_tau(self):
                self.end_ns = snap_ns
        counts, verdict = self.law.cycle(self, snap_ns, q, xyz, est, play)
        if verdict is not None:
            zero = np.zeros(6, dtype=np.int64)
            return Step(zero, ref, self._segment(), "holding", verdict)
        state = "settling" if self.end_ns is not None else "tracking"
        return Step(counts, ref, self._segment(), state)

    def _segment(self) -> int:
        return self.law.segment(self)

    def _decelerate(self, last: np.ndarray) -> Step:
        step = self.config.cancel_decel * self.config.cycle_s / COUNT_RAD_S
        peak = float(np.max(np.abs(last)))
        ref = self.ref.position(self.tau)
        if peak <= step:
            zero = np.zeros(6, dtype=np.int64)
            end = End(ResultStatus.CANCELLED, EndCause.CANCEL_REQUEST, "cancelled")
            return Step(zero, ref, self._segment(), "decelerating", end)
        wanted = np.abs(last) * ((peak - step) / peak)
        mag = np.minimum(np.abs(last), np.floor(wanted + 0.5))
        return Step(np.asarray(np.sign(last) * mag, dtype=np.int64), ref, -1, "decelerating")

    def _abort(self, ref: list[float], reason: str) -> Step:
        zero = np.zeros(6, dtype=np.int64)
        end = End(ResultStatus.ABORTED, EndCause.TOLERANCE, reason)
        return Step(zero, ref, self._segment(), "holding", end)

    # -- via points and verdicts ---------------------------------------------------------

    def record(self, error: float, stamp_ns: int) -> None:
        """One via point's error [m], measured at ``stamp_ns`` [ns]."""
        self.via_errors.append(error)
        self.via_stamps.append(stamp_ns)

    def judge(
        self,
        snap_ns: int,
        q: np.ndarray,
        xyz: Vec3,
        at_rest: bool,
    ) -> End | None:
        """Success, abort, or None (keep going), once the reference has ended.

        ``at_rest``: nothing is in flight, so zeros from now on leave the arm where it is.
        """
        goal, end = self.goal, self.ref.end
        self.final_error = math.dist(xyz, self.ref.via_xyz[-1])
        joints = violation(end - q, self.goal_tol, "goal")
        close = self.final_error <= goal.position_tolerance and joints is None
        if close and at_rest:
            return End(
                ResultStatus.SUCCEEDED,
                EndCause.REACHED,
                f"reached the end within {self.final_error * 1000:.2f} mm "
                f"(position_tolerance {goal.position_tolerance * 1000:.2f} mm)",
            )
        late = (snap_ns - (self.end_ns or snap_ns)) / 1e9
        if late > goal.goal_time_tolerance:
            what = joints or (
                "the arm did not come to rest"
                if close
                else f"final position error {self.final_error * 1000:.2f} mm exceeds "
                f"position_tolerance {goal.position_tolerance * 1000:.2f} mm"
            )
            why = f"{what} {late:.2f} s after the end (goal_time_tolerance)"
            return End(ResultStatus.ABORTED, EndCause.TOLERANCE, why)
        return self.law.unsettled(self, q)

    def replan(self, q: np.ndarray) -> None:
        """Follow a local rest-to-rest move from ``q`` [rad] to the last knot."""
        cfg = self.config
        way = float(np.max(np.abs(self.ref.end - q)))
        duration = max(cfg.settle_min_s, way / cfg.settle_speed)
        self.settle = Reference(rest_to_rest(q, self.ref.end, duration, cfg.arm), arm=cfg.arm)
        self.settle_tau = 0.0
        self.settles += 1
