"""A task file's ``follow`` step: its keys -> the step (``services/sequencer/taskfile.py``).

::

    [[step]]
    follow = "mouth"            # the tracker to follow (its frames' source on target/pose)
    standoff_mm = 60            # optional: from the target along the approach axis
    offset_mm = [0, 0, 60]      # optional: the tracked point in the gripper frame (a rim)
    approach = [1, 0, 0]        # optional: from the target to the standoff point, its frame
    hold_s = 10                 # optional: hold this long once there (default: until done)
    max_speed_mm_s = 100        # optional: speed cap (default: the controller's)
    close = true                # optional: the closer approach (never the default) ...
    close_clearance_mm = 20     # ... the rim's clearance from the person

Without ``hold_s`` the step holds until the supervisor says ``done`` (``manus task done``,
``TaskControl`` action ``done``). Units are the task file's (mm), the step's are SI.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from schemas.follow import FollowGoal
from schemas.sequencing import StepKind, TaskStep

OPTIONS = (
    "standoff_mm",
    "offset_mm",
    "approach",
    "hold_s",
    "max_speed_mm_s",
    "close",
    "close_clearance_mm",
)
"""The keys a follow step may carry besides ``follow``."""

MAX_HOLD_S = 3600.0
"""Longest hold [s]."""

Report = Callable[[str, str], None]
"""(key, message): report one problem of the step."""


def _number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _triple(value: Any) -> bool:
    return isinstance(value, list) and len(value) == 3 and all(_number(v) for v in value)


def follow_step(raw: dict[str, Any], where: str, report: Report) -> TaskStep | None:
    """The follow step of the table ``raw`` (None: a problem was reported)."""
    source = raw["follow"]
    ok = True
    if not isinstance(source, str) or not source:
        report("follow", f'follow takes the tracker\'s name, e.g. "mouth" (got {source!r})')
        ok = False
    checks: list[tuple[str, Callable[[Any], bool], str]] = [
        ("standoff_mm", lambda v: _number(v) and 0.0 <= v <= 500.0, "a distance in 0..500 mm"),
        ("offset_mm", lambda v: _triple(v) and all(abs(x) <= 300.0 for x in v), "3 numbers [mm]"),
        ("approach", lambda v: _triple(v) and any(v), "3 numbers, not all 0"),
        ("hold_s", lambda v: _number(v) and 0.0 < v <= MAX_HOLD_S, f"0..{MAX_HOLD_S:g} s"),
        ("max_speed_mm_s", lambda v: _number(v) and 0.0 < v <= 250.0, "0..250 mm/s"),
        ("close", lambda v: isinstance(v, bool), "true or false"),
        ("close_clearance_mm", lambda v: _number(v) and 5.0 <= v <= 500.0, "5..500 mm"),
    ]
    for key, good, what in checks:
        if key in raw and not good(raw[key]):
            report(key, f"{key} must be {what}, got {raw[key]!r}")
            ok = False
    if not ok:
        return None
    goal = FollowGoal(
        goal_id="",
        source=source,
        standoff=float(raw.get("standoff_mm", 0.0)) / 1000.0,
        approach=[float(v) for v in raw.get("approach", [1.0, 0.0, 0.0])],
        offset=[float(v) / 1000.0 for v in raw.get("offset_mm", [0.0, 0.0, 0.0])],
        max_speed=float(raw.get("max_speed_mm_s", 0.0)) / 1000.0,
        close=bool(raw.get("close", False)),
        close_clearance=float(raw.get("close_clearance_mm", 20.0)) / 1000.0,
    )
    hold = float(raw.get("hold_s", 0.0))
    return TaskStep(kind=StepKind.FOLLOW, follow=goal, duration=hold, where=where)
