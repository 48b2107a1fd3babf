"""Goal planning: a :class:`~schemas.goals.ReachRequest` and a start configuration ->
the same :class:`~schemas.planning.Trajectory` a via-point plan gives, or a refusal.

- ``joints``, ``pose``, ``named``, ``object``: the goal's target
  (:mod:`.goal_target`), its goal states (:mod:`.goal_states`: every valid IK branch), a
  path to one of them (:mod:`.search`: OMPL), time along it (:mod:`.retime`: the
  spline, the limits, the sweep);
- ``line``: the straight Cartesian line (:mod:`.line`), timed and swept.

No clock and no unseeded randomness: the same request, start and scene give the same
trajectory (docs/reach.md, Determinism). Every refusal is a
:class:`~services.planner.errors.PlanningError` whose message names the reason.
"""

from __future__ import annotations

import math
import weakref
from typing import Any

import numpy as np

from manus.collision import CollisionModel
from manus.kinematics import fk, fk_batch
from manus.named_poses import NamedPose
from manus.sweep import sweep
from schemas.goals import GoalKind, ReachRequest
from schemas.planning import Trajectory
from services.planner.config import PlannerConfig
from services.planner.errors import refuse
from services.planner.goal_states import goal_states
from services.planner.goal_target import resolve_target
from services.planner.line import end_pose, solve_line
from services.planner.retime import Timed, Unfit, fit, within_limits, work_area_problem
from services.planner.search import PLANNER, Found, SearchSettings, search
from services.planner.spline import PiecewisePolynomial, clamped_cubic_velocities
from services.planner.validity import CoalValidity, FastValidity, FreeSpace, Validity
from services.planner.work_area import WorkArea

_VALIDITY: weakref.WeakKeyDictionary[CollisionModel, tuple[Validity, Validity]] = (
    weakref.WeakKeyDictionary()
)


def validity_of(model: CollisionModel) -> tuple[Validity, Validity]:
    """The fast and the exact :class:`Validity` of ``model`` (built once per model: the
    exact one's cache lives with it)."""
    found = _VALIDITY.get(model)
    if found is None:
        found = _VALIDITY[model] = (FastValidity(model), CoalValidity(model))
    return found


def plan_reach(
    request: ReachRequest,
    start: np.ndarray,
    config: PlannerConfig,
    model: CollisionModel | None,
    poses: dict[str, NamedPose],
) -> Trajectory:
    """Plan ``request`` from ``start`` [rad], shape (6,) (see the module docstring).

    Raises:
        PlanningError: the reason and where.
    """
    arm = config.arm
    start = np.asarray(start, dtype=float)
    _check_start(start, config, model)
    scene = model.scene if model is not None else None
    if request.goal.kind == GoalKind.LINE:
        return _line(request, start, config, model)
    target = resolve_target(request.goal, scene, poses)
    validity = _validity(model)
    work = WorkArea(arm)
    goals = goal_states(target, start, arm, validity[1], scene, request.seed, work)
    settings = SearchSettings(request.seed, request.budget, config.padding)
    found = search(start, goals, validity, work, arm.lower_array, arm.upper_array, settings)
    if not isinstance(found, Found):
        T = fk(found.closest, arm)[:3, 3]
        G = fk(goals[found.goal], arm)[:3, 3]
        raise refuse(
            "no_path",
            f"{target.label}: no collision-free path found in {found.iterations} iterations "
            f"of {PLANNER} (seed {request.seed}; {found.states[0]} configurations grown from "
            f"the start, {found.states[1]} from the goal); the closest it came: "
            f"{math.degrees(found.distance):.1f} deg from a goal configuration in joint "
            f"space, the gripper {np.linalg.norm(T - G) * 1e3:.0f} mm from its goal",
            value=found.distance,
        )
    timed = fit(
        found.path,
        arm,
        request.speed,
        quintic=request.interpolation == "quintic",
        model=model,
        work=work,
    )
    if isinstance(timed, Unfit):
        raise refuse("collision", f"{target.label}: the planned path's trajectory {timed.problem}")
    how = (
        "a straight joint motion"
        if found.iterations == 0
        else (f"{PLANNER} (seed {request.seed}, {found.iterations} iterations)")
    )
    notes = [f"{target.label}: reached by {how}, {len(found.path)} waypoints", *timed.notes]
    return _trajectory(timed, request, config, model, notes)


def _validity(model: CollisionModel | None) -> tuple[Validity, Validity]:
    if model is None:
        return FreeSpace(), FreeSpace()
    return validity_of(model)


def _check_start(start: np.ndarray, config: PlannerConfig, model: CollisionModel | None) -> None:
    arm = config.arm
    if start.shape != (6,) or not np.isfinite(start).all():
        raise refuse("invalid", f"start configuration must be 6 finite angles, got {start}")
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
    if model is not None:
        exact = validity_of(model)[1]
        if exact.margins(start).tightest < 0.0:
            raise refuse(
                "collision",
                f"the start configuration is already too close: "
                f"{exact.explain(start).describe()}; move the arm clear "
                "by hand (jog) first",
            )


def _line(
    request: ReachRequest, start: np.ndarray, config: PlannerConfig, model: CollisionModel | None
) -> Trajectory:
    arm = config.arm
    line = solve_line(start, end_pose(request.goal, fk(start, arm)), config, request.speed)
    zero = np.zeros(6)
    velocities = clamped_cubic_velocities(line.times, line.knots, zero, zero)
    curve = PiecewisePolynomial.hermite(line.times, line.knots, velocities)
    notes = [line.label]
    stretch = within_limits(curve, arm, 1.0)
    if stretch > 1.0:
        curve = curve.stretched(stretch)
        velocities = velocities / stretch
        notes.append(f"slowed {stretch:.3f}x to keep the joints within their limits")
    seg, problem = work_area_problem(curve, WorkArea(arm))
    if seg >= 0:
        mm = line.along[seg + 1] * 1e3
        raise refuse(
            "zone",
            f"{line.label}: by {mm:.0f} mm of {line.along[-1] * 1e3:.0f} mm the line leaves "
            f"the arm's own work area ({problem}): the arm refuses to go there",
        )
    clearance = None
    if model is not None:
        ex = curve.extremes(1)
        found = sweep(model, curve.times, np.maximum(-ex.low, ex.high), curve.evaluate)
        bad = found.violation
        if bad is not None:
            mm = float(np.interp(bad.time, curve.times, line.along)) * 1e3
            raise refuse(
                "collision",
                f"{line.label}: at {mm:.0f} mm of {line.along[-1] * 1e3:.0f} mm the "
                f"{bad.describe()}",
                value=float(bad.distance),
                limit=float(bad.check.required),
            )
        clearance = found.worst
    timed = Timed(curve, line.knots, velocities, None, clearance, [])
    return _trajectory(timed, request, config, model, notes)


def _trajectory(
    timed: Timed,
    request: ReachRequest,
    config: PlannerConfig,
    model: CollisionModel | None,
    notes: list[str],
) -> Trajectory:
    curve = timed.curve
    duration = curve.duration
    preview_t: np.ndarray = np.zeros(0)
    preview_dt = 0.0
    if request.preview_dt > 0.0:
        preview_dt = max(request.preview_dt, duration / (config.max_preview_points - 1))
        preview_t = np.arange(math.floor(duration / preview_dt) + 1) * preview_dt
        if duration - preview_t[-1] > 1e-9:
            preview_t = np.append(preview_t, duration)
    knots = timed.knots
    xyz = fk_batch(np.vstack([knots, curve.evaluate(preview_t)]), config.arm)[:, :3, 3]
    accelerations = [] if timed.accelerations is None else _rows(timed.accelerations)
    scene = model.scene if model is not None else None
    return Trajectory(
        times=_rows(curve.times),
        positions=_rows(knots),
        velocities=_rows(timed.velocities),
        accelerations=accelerations,
        via_xyz=_rows(xyz[: len(knots)]),
        via_lines=[0] * len(knots),
        preview_xyz=_rows(xyz[len(knots) :]),
        preview_dt=preview_dt,
        time_scale=1.0,
        notes=notes,
        clearance=None if timed.clearance is None else timed.clearance.report(),
        scene_version=scene.version if scene is not None else -1,
    )


def _rows(a: np.ndarray) -> list[Any]:
    out: list[Any] = np.asarray(a, dtype=float).tolist()
    return out
