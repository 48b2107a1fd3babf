"""The goal planners behind :class:`~services.planner.planner.Planner`: a goal and a start
configuration -> the same :class:`~schemas.planning.Trajectory` a via-point plan gives.

:class:`GoalPlanner` serves ``joints``, ``pose``, ``named`` and ``object`` goals
(:mod:`schemas.goals`):

1. the goal's target (:mod:`.goal_target`) and its goal states: every valid IK branch
   (:mod:`.goal_states`);
2. a path to one of them: the straight joint motion, else OMPL's search and
   simplification (:mod:`.search`, :mod:`.floors`: the scene with a padding, the arm's
   own work area);
3. time along it: the spline, the limits, the curve checked again (:mod:`.retime`).

:class:`LinePlanner` serves ``line`` motions (:mod:`.line`): solved sample by sample,
timed, kept in the work area and swept (its refusal names the millimetre along it).

:meth:`Planner.plan <services.planner.planner.Planner.plan>` then applies what every kind
shares (the speed limits, the collision sweep of the final curve, the message). A resumed
goal is planned again from where the arm is, to the same goal; a resumed line goes on to
the end pose it was planned to. No clock and no unseeded randomness: the same request,
start and scene give the same trajectory (docs/reach.md, Determinism).
"""

from __future__ import annotations

import math
import weakref

import numpy as np

from manus.collision import CollisionModel
from manus.kinematics import fk
from manus.named_poses import NamedPose, named_poses
from manus.sweep import sweep
from schemas.goals import LineMotion, TargetGoal
from schemas.planning import KnotKind, PlanResume
from services.planner.config import PlannerConfig
from services.planner.errors import refuse
from services.planner.goal_states import goal_states
from services.planner.goal_target import resolve_target
from services.planner.labels import KnotLabels
from services.planner.line import end_pose, solve_line
from services.planner.planner import Planner, Route, SceneInUse
from services.planner.retime import Unfit, fit, within_limits, work_area_problem
from services.planner.search import PLANNER, Found, SearchSettings, search
from services.planner.spline import PiecewisePolynomial, clamped_cubic_velocities
from services.planner.validity import CoalValidity, FastValidity, FreeSpace, Validity
from services.planner.work_area import WorkArea

_VALIDITY: weakref.WeakKeyDictionary[CollisionModel, tuple[Validity, Validity]] = (
    weakref.WeakKeyDictionary()
)


def validity_of(model: CollisionModel | None) -> tuple[Validity, Validity]:
    """The fast and the exact :class:`Validity` of ``model``, built once per model (the
    exact one's cache lives with it); without a scene, free space."""
    if model is None:
        return FreeSpace(), FreeSpace()
    found = _VALIDITY.get(model)
    if found is None:
        found = _VALIDITY[model] = (FastValidity(model), CoalValidity(model))
    return found


def goal_labels(source: str, n: int) -> KnotLabels:
    """The start, ``n - 2`` waypoints and the goal."""
    kinds = (KnotKind.START, *(KnotKind.WAYPOINT,) * (n - 2), KnotKind.GOAL)
    return KnotLabels(source=source, kinds=kinds, via_indices=(-1,) * n, lines=(0,) * n)


def check_start(start: np.ndarray, config: PlannerConfig, model: CollisionModel | None) -> None:
    """Refuse a start beyond a joint limit, or already too close to something."""
    arm = config.arm
    for j in range(6):
        if not arm.lower[j] <= start[j] <= arm.upper[j]:
            lim = arm.lower[j] if start[j] < arm.lower[j] else arm.upper[j]
            raise refuse(
                "joint_limit",
                f"the start configuration: joint {j + 1} at {math.degrees(start[j]):.2f} deg "
                f"is beyond its limit {math.degrees(lim):.1f} deg",
                joint=j + 1,
                value=float(start[j]),
                limit=float(lim),
            )
    exact = validity_of(model)[1]
    if model is not None and exact.margins(start).tightest < 0.0:
        raise refuse(
            "collision",
            f"the start configuration is already too close: {exact.explain(start).describe()}; "
            "move the arm clear by hand (jog) first",
        )


class GoalPlanner(Planner[TargetGoal]):
    """Plans ``joints``, ``pose``, ``named`` and ``object`` goals (see the module
    docstring).

    Raises:
        NamedPoseError: the user's poses file (``config.poses``) is malformed.
    """

    def __init__(self, config: PlannerConfig) -> None:
        super().__init__(config)
        self.poses: dict[str, NamedPose] = named_poses(config.poses)
        self.work = WorkArea(config.arm)

    def route(
        self, motion: TargetGoal, start: np.ndarray, resume: PlanResume | None, scene: SceneInUse
    ) -> Route:
        # A resumed goal: the same goal from where the arm is (the search finds its way
        # again; the paused plan's path may no longer be the best one from here).
        with scene.checking:
            return self._route(motion, start, scene.collision)

    def _route(self, motion: TargetGoal, start: np.ndarray, model: CollisionModel | None) -> Route:
        config, arm = self.config, self.config.arm
        check_start(start, config, model)
        scene = model.scene if model is not None else None
        target = resolve_target(motion, scene, self.poses)
        fast, exact = validity_of(model)
        options = motion.search
        goals = goal_states(target, start, arm, exact, scene, options.seed, self.work)
        settings = SearchSettings(options.seed, options.budget, config.padding)
        found = search(
            start, goals, (fast, exact), self.work, arm.lower_array, arm.upper_array, settings
        )
        if not isinstance(found, Found):
            gap = fk(found.closest, arm)[:3, 3] - fk(goals[found.goal], arm)[:3, 3]
            raise refuse(
                "no_path",
                f"{target.label}: no collision-free path found in {found.iterations} "
                f"iterations of {PLANNER} (seed {options.seed}; {found.states[0]} "
                f"configurations grown from the start, {found.states[1]} from the goal); the "
                f"closest it came: {math.degrees(found.distance):.1f} deg from a goal "
                f"configuration in joint space, the gripper {np.linalg.norm(gap) * 1e3:.0f} mm "
                "from its goal",
                value=found.distance,
            )
        timed = fit(
            found.path,
            arm,
            options.speed,
            quintic=options.interpolation == "quintic",
            valid=None if model is None else fast.valid_many,
            work=self.work,
        )
        if isinstance(timed, Unfit):
            raise refuse("collision", f"{target.label}: the path's trajectory {timed.problem}")
        how = (
            "a straight joint motion"
            if found.iterations == 0
            else f"{PLANNER} (seed {options.seed}, {found.iterations} iterations)"
        )
        notes = [f"{target.label}: reached by {how}, {len(found.path)} waypoints", *timed.notes]
        return Route(
            times=timed.curve.times,
            knots=timed.knots,
            velocities=timed.velocities,
            accelerations=timed.accelerations,
            curve=timed.curve,
            labels=goal_labels(target.label, len(timed.knots)),
            speed_scaling=False,
            notes=notes,
        )


class LinePlanner(Planner[LineMotion]):
    """Plans straight Cartesian lines (see the module docstring)."""

    def __init__(self, config: PlannerConfig) -> None:
        super().__init__(config)
        self.work = WorkArea(config.arm)

    def route(
        self, motion: LineMotion, start: np.ndarray, resume: PlanResume | None, scene: SceneInUse
    ) -> Route:
        arm = self.config.arm
        if resume is not None:  # on to the end pose the line was planned to
            T1 = fk(np.asarray(resume.trajectory.positions[-1], dtype=float), arm)
        else:
            T1 = end_pose(motion, fk(start, arm))
        with scene.checking:
            check_start(start, self.config, scene.collision)
            line = solve_line(start, T1, self.config, motion.speed)
            zero = np.zeros(6)
            velocities = clamped_cubic_velocities(line.times, line.knots, zero, zero)
            curve = PiecewisePolynomial.hermite(line.times, line.knots, velocities)
            notes = [line.label]
            stretch = within_limits(curve, arm, 1.0)
            if stretch > 1.0:
                curve = curve.stretched(stretch)
                velocities = velocities / stretch
                notes.append(f"slowed {stretch:.3f}x to keep the joints within their limits")
            seg, problem = work_area_problem(curve, self.work)
            if seg >= 0:
                raise refuse(
                    "zone",
                    f"{line.label}: by {line.along[seg + 1] * 1e3:.0f} mm of "
                    f"{line.along[-1] * 1e3:.0f} mm the line reaches the edge of the arm's own "
                    f"work area ({problem}): the arm refuses to go beyond it",
                )
            if scene.collision is not None:
                self._sweep(scene.collision, curve, line.along, line.label)
        labels = goal_labels(line.label, len(line.knots))
        return Route(curve.times, line.knots, velocities, None, curve, labels, False, notes)

    @staticmethod
    def _sweep(
        model: CollisionModel, curve: PiecewisePolynomial, along: np.ndarray, label: str
    ) -> None:
        """Refuse a line whose curve comes too close to something, naming the millimetre
        along it (the shared sweep would name a knot)."""
        ex = curve.extremes(1)
        found = sweep(model, curve.times, np.maximum(-ex.low, ex.high), curve.evaluate)
        bad = found.violation
        if bad is not None:
            mm = float(np.interp(bad.time, curve.times, along)) * 1e3
            raise refuse(
                "collision",
                f"{label}: at {mm:.0f} mm of {along[-1] * 1e3:.0f} mm the {bad.describe()}",
                value=float(bad.distance),
                limit=float(bad.check.required),
            )
