"""Control modes: the seam where a trajectory goal's control law plugs in.

A :class:`ControlLaw` decides, for one running trajectory goal
(:class:`~services.controller.tracking.TrajectoryRun`): its time base (where trajectory
time starts, when the reference has ended), how its via-point errors are measured, and
each cycle's command and verdict. ``TrajectoryGoal.mode`` names one of :data:`LAWS`:

- :class:`DefaultLaw` (``default``): one global time base starting when the first command
  acts; via errors interpolated at the knot times; the delay-compensated dead-beat law
  (:func:`~services.controller.laws.default_law`); the end is judged once nothing is in
  flight.
- :class:`ThesisLaw` (``thesis``): the 2005 thesis's loop for comparison: per-segment
  timing, via errors where a segment ends, qdot = qdot_ref + K (q_ref - q), and local
  re-plans after the last via point (docs/protocol.md, the thesis's control loop).

Each implements :class:`~services.controller.tracking.ControlLaw`, the seam the run
calls. A new mode is one class here and one entry in :data:`LAWS` (and the value in
:class:`schemas.control.ControlMode`). The run keeps the state; a law holds none.
"""

from __future__ import annotations

import math

import numpy as np

from manus.kinematics import Vec3, gripper_position
from schemas.control import ControlMode, EndCause, ResultStatus
from services.controller.backlash import PlayModel
from services.controller.command_source import End
from services.controller.estimator import DriveEstimator
from services.controller.laws import default_law, thesis_law
from services.controller.tracking import ControlLaw, TrajectoryRun


class DefaultLaw:
    """The default mode (see the module docstring and :mod:`.tracking`)."""

    def start_tau(self, run: TrajectoryRun) -> float:
        return -run.scale * run.config.command_delay_ms / 1000.0

    def tau_at_command(self, run: TrajectoryRun) -> float:
        return run.tau + run.scale * run.config.command_delay_ms / 1000.0

    def end_tau(self, run: TrajectoryRun) -> float:
        return run.ref.duration

    def segment(self, run: TrajectoryRun) -> int:
        return run.ref.traj.segment(run.tau)

    def measure(self, run: TrajectoryRun, snap_ns: int, q: np.ndarray, xyz: Vec3) -> None:
        """Each knot's error at its time, the measurement interpolated between the two
        snapshots around it."""
        times = run.ref.times
        while len(run.via_errors) < len(times) and times[len(run.via_errors)] <= run.tau:
            i = len(run.via_errors)
            prev = run.prev
            if prev is None or run.tau <= prev[0]:
                q_i, stamp = q, snap_ns
            else:
                frac = min(1.0, max(0.0, (times[i] - prev[0]) / (run.tau - prev[0])))
                q_i = prev[1] + frac * (q - prev[1])
                stamp = prev[2] + round(frac * (snap_ns - prev[2]))
            at = gripper_position(q_i, run.config.arm)
            run.record(math.dist(at, run.ref.via_xyz[i]), stamp)
        run.prev = (run.tau, q.copy(), snap_ns)

    def cycle(
        self,
        run: TrajectoryRun,
        snap_ns: int,
        q: np.ndarray,
        xyz: Vec3,
        est: DriveEstimator,
        play: PlayModel | None,
    ) -> tuple[np.ndarray, End | None]:
        ref, tau = run.current_reference()
        holding = run.end_ns is not None
        counts = default_law(
            run.config, ref, (tau, run.tau), run.scale, q, est, play, run.quantizer, holding
        )
        at_rest = not est.in_flight  # a zero now stops the arm here
        verdict = run.judge(snap_ns, q, xyz, at_rest) if holding else None
        return counts, verdict

    def unsettled(self, run: TrajectoryRun, q: np.ndarray) -> End | None:
        return None


class ThesisLaw:
    """The thesis's mode (see the module docstring and :mod:`.tracking`)."""

    def start_tau(self, run: TrajectoryRun) -> float:
        return 0.0

    def tau_at_command(self, run: TrajectoryRun) -> float:
        return run.tau

    def end_tau(self, run: TrajectoryRun) -> float:
        return float(run.ref.times[-1])

    def segment(self, run: TrajectoryRun) -> int:
        return run.segment

    def measure(self, run: TrajectoryRun, snap_ns: int, q: np.ndarray, xyz: Vec3) -> None:
        """A segment ends when the gripper is within ``thesis_via_threshold_m`` of its via
        point or its time is over; its error is the one measured then, and the next
        segment restarts at its first knot (per-segment timing)."""
        ref = run.ref
        if not run.via_errors:
            run.record(math.dist(xyz, ref.via_xyz[0]), snap_ns)
        last = len(ref.times) - 1
        if run.segment >= last:
            return
        nxt = run.segment + 1
        distance = math.dist(xyz, ref.via_xyz[nxt])
        if distance < run.config.thesis_via_threshold_m or run.tau >= ref.times[nxt]:
            run.record(distance, snap_ns)
            run.segment = nxt
            run.tau = float(ref.times[nxt])

    def cycle(
        self,
        run: TrajectoryRun,
        snap_ns: int,
        q: np.ndarray,
        xyz: Vec3,
        est: DriveEstimator,
        play: PlayModel | None,
    ) -> tuple[np.ndarray, End | None]:
        # Judged first: a re-plan decided now is followed from this cycle on.
        verdict = run.judge(snap_ns, q, xyz, True) if run.end_ns is not None else None
        ref, tau = run.current_reference()
        return thesis_law(run.config, ref, tau, run.scale, q), verdict

    def unsettled(self, run: TrajectoryRun, q: np.ndarray) -> End | None:
        """After the last via point: re-plan locally (a rest-to-rest quintic from the
        measured angles to the last knot) until within tolerance, at most
        ``max_settles`` times."""
        if run.settle is not None and run.settle_tau < run.settle.duration:
            return None
        if run.settles >= run.config.max_settles:
            return End(
                ResultStatus.ABORTED,
                EndCause.TOLERANCE,
                f"final position error {run.final_error * 1000:.2f} mm still above "
                f"{run.goal.position_tolerance * 1000:.2f} mm after {run.settles} re-plans",
            )
        run.replan(q)
        return None


LAWS: dict[str, ControlLaw] = {ControlMode.DEFAULT: DefaultLaw(), ControlMode.THESIS: ThesisLaw()}
"""The control law of each :class:`~schemas.control.ControlMode`."""
