"""Which planner serves each kind of motion: one line per kind.

A new kind of motion is one message class in :mod:`schemas.planning` (a member of
:data:`~schemas.planning.MOTIONS`), one planner module (a
:class:`~services.planner.planner.Planner` subclass) and one line here. The schema
declares only the kinds listed here (a test keeps the two equal): a request for any other
kind does not decode.
"""

from __future__ import annotations

from typing import Any

from schemas.goals import JointGoal, LineMotion, NamedGoal, ObjectGoal, PoseGoal
from schemas.motion import Motion
from schemas.planning import ViaPointContinuation, ViaPointPath
from services.planner.goal_planner import GoalPlanner, LinePlanner
from services.planner.planner import Planner
from services.planner.via_point_planner import ContinuationPlanner, ViaPointPlanner

PLANNERS: dict[type[Motion], type[Planner[Any]]] = {
    ViaPointPath: ViaPointPlanner,
    ViaPointContinuation: ContinuationPlanner,
    JointGoal: GoalPlanner,
    PoseGoal: GoalPlanner,
    NamedGoal: GoalPlanner,
    ObjectGoal: GoalPlanner,
    LineMotion: LinePlanner,
}
"""The planner class of each kind of motion."""
