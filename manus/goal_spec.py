"""A goal as a user writes it (a task file's ``reach`` step): millimetres, degrees, one
name or one table -> a goal motion of :mod:`schemas.goals`.

    reach = "drink"                                        # a named pose
    reach = {named = "drink"}
    reach = {pose = [560, 100, -150, 0, 90, 0]}            # X Y Z YAW PITCH ROLL, base frame
    reach = {pose = [550, 50, -120, 0, 180, 0], free_axis = true, tolerance_mm = 5}
    reach = {joints = [30, 20, -40, 10, -50, 0]}           # DH joint angles
    reach = {object = "table", pose = [-250, -300, 130, 0, 90, 0]}   # in the object's frame
    reach = {approach = 40}                                # along the gripper's axis [mm]
    reach = {approach = -80}                               # a retreat
    reach = {line_to = [500, -50, -60]}                    # a straight line, orientation kept
    reach = {line_tool = [0, 20, 0]}                       # by a displacement, gripper frame

Options: ``free_axis``, ``tolerance_mm``, ``tolerance_deg`` (pose and object goals),
``seed``, ``budget``, ``interpolation`` (goals searched for) and ``speed`` (all). A pose is
``X Y Z YAW PITCH ROLL`` [mm, deg], the command line's order (``manus kin fk``).
"""

from __future__ import annotations

import math
from typing import Any

from manus.errors import ManusError, SchemaError
from schemas.goals import (
    JointGoal,
    LineFrame,
    LineMotion,
    NamedGoal,
    ObjectGoal,
    PoseGoal,
    Search,
    Tolerance,
)
from schemas.motion import Motion

KINDS = ("named", "pose", "joints", "object", "approach", "line_to", "line_tool")
"""The keys naming a goal (exactly one)."""

OPTIONS = ("free_axis", "tolerance_mm", "tolerance_deg", "seed", "budget", "speed", "interpolation")
"""The keys refining it."""


class GoalSpecError(ManusError, ValueError):
    """A goal is written wrong; the message names the key and what is allowed."""


def goal_from_spec(spec: Any) -> Motion:
    """The goal motion ``spec`` writes (see the module docstring).

    Raises:
        GoalSpecError: naming the key, the value and what is allowed.
    """
    if isinstance(spec, str):
        return NamedGoal(name=spec)
    if not isinstance(spec, dict):
        raise GoalSpecError(f"a goal is a named pose or a table of {', '.join(KINDS)}")
    unknown = sorted(set(spec) - set(KINDS) - set(OPTIONS) - {"pose"})
    if unknown:
        raise GoalSpecError(
            f"unknown key {unknown[0]!r} (goals: {', '.join(KINDS)}; options: {', '.join(OPTIONS)})"
        )
    kinds = [k for k in KINDS if k in spec and not (k == "pose" and "object" in spec)]
    if len(kinds) != 1:
        raise GoalSpecError(f"give exactly one of {', '.join(KINDS)} (found {kinds or 'none'})")
    try:
        motion = _motion(kinds[0], spec)
        # Decoding checks every field's range, as the planner's queryable will.
        return type(motion).from_dict(motion.to_dict())
    except SchemaError as exc:  # a value out of its range
        raise GoalSpecError(str(exc)) from exc


def _motion(kind: str, spec: dict[str, Any]) -> Motion:
    speed = _number(spec, "speed", 0.5)
    if kind in ("approach", "line_to", "line_tool"):
        _only(spec, kind, ("speed",))
        if kind == "approach":
            return LineMotion(
                xyz=[0.0, 0.0, _number(spec, "approach") * 1e-3], frame=LineFrame.TOOL, speed=speed
            )
        values = _numbers(spec, kind, (3, 6) if kind == "line_to" else (3,))
        ypr = [math.radians(v) for v in values[3:]] or None
        frame = LineFrame.BASE if kind == "line_to" else LineFrame.TOOL
        return LineMotion(xyz=[v * 1e-3 for v in values[:3]], ypr=ypr, frame=frame, speed=speed)
    search = Search(
        seed=int(_number(spec, "seed", 1)),
        budget=int(_number(spec, "budget", 3000)),
        speed=speed,
        interpolation=str(spec.get("interpolation", "cubic")),
    )
    if kind == "named":
        _only(spec, kind, ("seed", "budget", "speed", "interpolation"))
        name = spec["named"]
        if not isinstance(name, str):
            raise GoalSpecError(f"named: a pose's name, got {name!r}")
        return NamedGoal(name=name, search=search)
    if kind == "joints":
        _only(spec, kind, ("seed", "budget", "speed", "interpolation"))
        return JointGoal(
            joints=[math.radians(v) for v in _numbers(spec, "joints", (6,))], search=search
        )
    tolerance = Tolerance(
        position=_number(spec, "tolerance_mm", 0.0) * 1e-3,
        angle=math.radians(_number(spec, "tolerance_deg", 0.0)),
        free_axis=_flag(spec, "free_axis"),
    )
    pose = _numbers(spec, "pose", (6,))
    xyz, ypr = [v * 1e-3 for v in pose[:3]], [math.radians(v) for v in pose[3:]]
    if kind == "object":
        name = spec["object"]
        if not isinstance(name, str):
            raise GoalSpecError(f"object: a scene object's name, got {name!r}")
        return ObjectGoal(name=name, xyz=xyz, ypr=ypr, tolerance=tolerance, search=search)
    return PoseGoal(xyz=xyz, ypr=ypr, tolerance=tolerance, search=search)


def _only(spec: dict[str, Any], kind: str, allowed: tuple[str, ...]) -> None:
    extra = sorted(set(spec) - {kind} - set(allowed))
    if extra:
        raise GoalSpecError(f"{extra[0]}: not an option of a {kind} goal ({', '.join(allowed)})")


def _number(spec: dict[str, Any], key: str, default: float | None = None) -> float:
    value = spec.get(key, default)
    if not (isinstance(value, int | float) and not isinstance(value, bool)) or not math.isfinite(
        value
    ):
        raise GoalSpecError(f"{key}: a finite number, got {value!r}")
    return float(value)


def _numbers(spec: dict[str, Any], key: str, lengths: tuple[int, ...]) -> list[float]:
    value = spec.get(key)
    if not isinstance(value, list) or len(value) not in lengths:
        want = " or ".join(str(n) for n in lengths)
        raise GoalSpecError(f"{key}: a list of {want} numbers, got {value!r}")
    return [_number({key: v}, key) for v in value]


def _flag(spec: dict[str, Any], key: str) -> bool:
    value = spec.get(key, False)
    if not isinstance(value, bool):
        raise GoalSpecError(f"{key}: true or false, got {value!r}")
    return value
