"""The object steps of a task file (:mod:`services.sequencer.taskfile`, docs/pick.md)::

[[step]]
pick = "cup"                        # the world model's object
[[step]]
place = "cup"
at = [950, -150, 790, 0, 0, 0]      # its centre, chair frame [mm]; yaw pitch roll [deg]
[[step]]
place = "cup"
on = "table"                        # or onto a scene object, under where it is held
[[step]]
place = "cup"
back = true                         # or back where this task's pick took it from
[[step]]
give = "cup"                        # to the hand-over pose near the user
[[step]]
give = "cup"
at = [350, -150, 1050, 150, 0, 0]   # or to this one: its centre [mm], the gripper's yaw [deg]
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from schemas.sequencing import StepKind, TaskStep

OBJECT_OPTIONS: dict[str, tuple[str, ...]] = {
    StepKind.PICK: (),
    StepKind.PLACE: ("at", "on", "back"),
    StepKind.GIVE: ("at",),
}
"""Keys an object step of each kind may carry besides its kind."""

Report = Callable[[str, str], None]
"""Reports a problem: (the key it is at, the message)."""


def object_step(kind: str, raw: dict[str, Any], where: str, report: Report) -> TaskStep | None:
    """The step of kind ``kind`` (pick, place, give) the table ``raw`` writes, or None
    after reporting every problem."""
    name = raw[kind]
    if not isinstance(name, str) or not name:
        report(kind, f'{kind} takes an object\'s id (a name, e.g. "cup"), got {name!r}')
        return None
    if kind == StepKind.PICK:
        return TaskStep(kind=kind, object=name, where=where)
    if kind == StepKind.GIVE:
        if "at" not in raw:
            return TaskStep(kind=kind, object=name, where=where)
        pose = _pose(raw["at"], report)
        return None if pose is None else TaskStep(kind=kind, object=name, at=pose, where=where)
    return _place(name, raw.get("at"), raw.get("on"), raw.get("back"), where, report)


def _place(name: str, at: Any, on: Any, back: Any, where: str, report: Report) -> TaskStep | None:
    if back is not None and back is not True:
        report("back", f"back takes true (put it back where the pick took it), got {back!r}")
        return None
    if (at is not None) + (on is not None) + (back is not None) != 1:
        report(
            StepKind.PLACE,
            "a place step needs one of at = [X, Y, Z, YAW, PITCH, ROLL], on = SURFACE or "
            "back = true",
        )
        return None
    if back:
        return TaskStep(kind=StepKind.PLACE, object=name, back=True, where=where)
    if on is not None:
        if not isinstance(on, str) or not on:
            report("on", f"on takes a scene object's name, got {on!r}")
            return None
        return TaskStep(kind=StepKind.PLACE, object=name, surface=on, where=where)
    pose = _pose(at, report)
    return (
        None if pose is None else TaskStep(kind=StepKind.PLACE, object=name, at=pose, where=where)
    )


def _pose(at: Any, report: Report) -> list[float] | None:
    """``at`` [mm, deg] in SI units [m, rad], or None after reporting the problem."""
    if not isinstance(at, list) or len(at) != 6 or not all(_finite(v) for v in at):
        report("at", f"at takes 6 numbers (X Y Z [mm], YAW PITCH ROLL [deg]), got {at!r}")
        return None
    return [float(v) * 1e-3 for v in at[:3]] + [math.radians(float(v)) for v in at[3:]]


def _finite(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
