"""The fixed set of goals of ``manus bench reach``: ``manus_stack/bench/reach_goals.yaml``.

Each entry is one plan in the default scene: where it starts and what it asks for, as a
user would give it (mm, deg; a pose is ``X Y Z YAW PITCH ROLL`` in the base frame, as
``manus kin fk`` prints it)::

    - {id: table-issue, area: over_table, start: unfolded, pose: [560, 100, -150, 0, 90, 0]}
    - {id: drink-from-folded, area: named, start: folded, named: drink}
    - {id: knee-to-table, area: around, start: knee-low, pose: [...]}
    - {id: approach, area: line, start: table-issue, line_tool: [0, 0, 40]}
    - {id: in-table, area: infeasible, start: unfolded, pose: [...],
       refused: goal_collision, why: the gripper inside the table top}

``start`` names a named pose, or the ``id`` of an earlier feasible entry (the plan starts
where that entry's plan ends). Exactly one goal key: ``pose``, ``joints``, ``named``,
``object`` (``[NAME, X, Y, Z, YAW, PITCH, ROLL]``), ``line_tool`` (a displacement in the
gripper's frame [mm]) or ``line_to`` (an end position in the base frame [mm], orientation
kept). Options of pose and object goals: ``free_axis``, ``tolerance_mm``,
``tolerance_deg``. An infeasible entry says the reason it must be refused with
(``refused``: a :class:`~schemas.planning.PlanErrorReason`) and ``why`` in words.
Problems are :class:`GoalSetError` naming the file, the line and the field.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path

import yaml

from manus.errors import ManusError
from manus.yaml_fields import FieldReader, join
from schemas.goals import (
    JointGoal,
    LineFrame,
    LineMotion,
    NamedGoal,
    ObjectGoal,
    PoseGoal,
    Tolerance,
)
from schemas.motion import Motion
from schemas.planning import PLAN_ERROR_REASONS

AREAS = (
    "over_table",
    "knees",
    "footrest",
    "named",
    "joints",
    "object",
    "around",
    "line",
    "infeasible",
)
"""Where in the scene a goal is (``infeasible``: it must be refused)."""

GOAL_KEYS = ("pose", "joints", "named", "object", "line_tool", "line_to")
_OPTIONS = ("free_axis", "tolerance_mm", "tolerance_deg")


class GoalSetError(ManusError, ValueError):
    """The goal set file is malformed; the message names the file, line and field."""


@dataclass(frozen=True)
class BenchGoal:
    """One entry of the set.

    Attributes:
        id: its name.
        area: one of :data:`AREAS`.
        start: a named pose, or the id of an earlier feasible entry.
        goal: the goal (a goal motion of :mod:`schemas.goals`).
        refused: the reason it must be refused with ('' when feasible).
        why: why it is infeasible, in words.
        line: its line in the file.
    """

    id: str
    area: str
    start: str
    goal: Motion
    refused: str = ""
    why: str = ""
    line: int = 0


def goal_set_path() -> Path:
    """The shipped goal set."""
    return Path(str(resources.files("manus_stack.bench") / "reach_goals.yaml"))


def load_goal_set(path: Path | None = None) -> list[BenchGoal]:
    """Read the goal set (default: :func:`goal_set_path`).

    Raises:
        GoalSetError: the first problem, with file, line and field.
    """
    file = path or goal_set_path()
    source = "manus_stack/bench/reach_goals.yaml" if path is None else str(file)
    reader = FieldReader(source, GoalSetError)
    root = reader.root(file.read_text(), "goal set")
    top = reader.mapping(root, "", ("version", "goals"), ())
    if reader.number(top["version"], "version") != 1:
        raise reader.fail(top["version"], "version", "this stack reads version 1")
    out: list[BenchGoal] = []
    ids: set[str] = set()
    feasible: set[str] = set()
    for i, item in enumerate(reader.items(top["goals"], "goals")):
        path_i = f"goals[{i}]"
        fields = reader.mapping(
            item, path_i, ("id", "area", "start"), (*GOAL_KEYS, *_OPTIONS, "refused", "why")
        )
        gid = reader.text(fields["id"], join(path_i, "id"))
        if gid in ids:
            raise reader.fail(fields["id"], join(path_i, "id"), f"id {gid!r} used twice")
        ids.add(gid)
        area = reader.text(fields["area"], join(path_i, "area"), AREAS)
        start = reader.text(fields["start"], join(path_i, "start"))
        if start not in ("unfolded", "folded", "home", "drink") and start not in feasible:
            raise reader.fail(
                fields["start"],
                join(path_i, "start"),
                f"{start!r} is neither a named pose nor an earlier feasible entry",
            )
        keys = [k for k in GOAL_KEYS if k in fields]
        if len(keys) != 1:
            raise reader.fail(item, path_i, f"needs exactly one of {', '.join(GOAL_KEYS)}")
        goal = _goal(reader, fields, keys[0], path_i)
        refused = ""
        if "refused" in fields:
            refused = reader.text(fields["refused"], join(path_i, "refused"), PLAN_ERROR_REASONS)
        if (area == "infeasible") != bool(refused):
            raise reader.fail(item, path_i, "an infeasible entry (only) says `refused` and `why`")
        why = str(fields["why"].value) if "why" in fields else ""
        if refused and not why:
            raise reader.fail(item, join(path_i, "why"), "say why it is infeasible")
        if not refused:
            feasible.add(gid)
        out.append(BenchGoal(gid, area, start, goal, refused, why, item.start_mark.line + 1))
    return out


def _goal(reader: FieldReader, fields: dict[str, yaml.Node], key: str, path: str) -> Motion:
    node = fields[key]
    where = join(path, key)
    tolerance = Tolerance(
        position=_option(reader, fields, path, "tolerance_mm") * 1e-3,
        angle=math.radians(_option(reader, fields, path, "tolerance_deg")),
        free_axis="free_axis" in fields and str(fields["free_axis"].value).lower() == "true",
    )
    if key == "pose":
        v = reader.vector(node, where, 6)
        return PoseGoal(xyz=_m(v[:3]), ypr=_rad(v[3:]), tolerance=tolerance)
    if key == "joints":
        return JointGoal(joints=_rad(reader.vector(node, where, 6)))
    if key == "named":
        return NamedGoal(name=str(node.value))
    if key == "object":
        items = reader.items(node, where)
        if len(items) != 7:
            raise reader.fail(node, where, "must be [NAME, X, Y, Z, YAW, PITCH, ROLL]")
        name = reader.text(items[0], f"{where}[0]")
        v = [reader.number(n, f"{where}[{k + 1}]") for k, n in enumerate(items[1:])]
        return ObjectGoal(name=name, xyz=_m(v[:3]), ypr=_rad(v[3:]), tolerance=tolerance)
    frame = LineFrame.TOOL if key == "line_tool" else LineFrame.BASE
    return LineMotion(xyz=_m(reader.vector(node, where)), frame=frame)


def _option(reader: FieldReader, fields: dict[str, yaml.Node], path: str, key: str) -> float:
    return reader.number(fields[key], join(path, key), minimum=0.0) if key in fields else 0.0


def _m(mm: list[float]) -> list[float]:
    return [v * 1e-3 for v in mm]


def _rad(deg: list[float]) -> list[float]:
    return [math.radians(v) for v in deg]
