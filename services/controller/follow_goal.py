"""A follow goal's settings checked against the controller's (docs/follow.md, The follow
goal): what :class:`~services.controller.follow_source.FollowSource` refuses as
``invalid``, and the :class:`~services.controller.follow_law.Settings` the law runs with."""

from __future__ import annotations

import math

from manus.errors import ManusError
from schemas.follow import FollowGoal
from services.controller.follow_config import FollowConfig
from services.controller.follow_law import Settings


class FollowError(ManusError, ValueError):
    """A follow goal that cannot run (the message names the field, value and limit)."""


def settings(
    goal: FollowGoal, cfg: FollowConfig, person_clearance: float, on_person: bool
) -> Settings:
    """The settings of ``goal`` (``person_clearance``: the scene's [m]; ``on_person``: the
    target moves with a person, whose clearance a standoff must keep without ``close``).

    Raises:
        FollowError: naming the field, the value and the limit.
    """
    if not goal.source:
        raise FollowError("`source` is empty: name the tracker to follow (TargetPose.source)")
    size = math.sqrt(sum(v * v for v in goal.approach))
    if not size > 1e-9:
        raise FollowError(f"`approach` {goal.approach} has no direction")
    if goal.max_speed > cfg.max_speed:
        raise FollowError(
            f"`max_speed` {goal.max_speed:g} m/s is above the controller's cap "
            f"{cfg.max_speed:g} m/s"
        )
    standoff = goal.standoff or cfg.standoff_m
    clearance = goal.close_clearance if goal.close else person_clearance
    if not goal.close and on_person and standoff < person_clearance:
        raise FollowError(
            f"`standoff` {standoff * 1e3:.0f} mm is inside the person's clearance "
            f"{person_clearance * 1e3:.0f} mm (a closer approach is `close`, explicitly)"
        )
    if goal.close and standoff < goal.close_clearance:
        raise FollowError(
            f"`standoff` {standoff * 1e3:.0f} mm is below `close_clearance` "
            f"{goal.close_clearance * 1e3:.0f} mm"
        )
    a, b, c = (v / size for v in goal.approach)
    x, y, z = goal.offset
    cap = goal.max_speed or cfg.max_speed
    lean = cfg.lean_margin_s if on_person else 0.0
    return Settings(standoff, (a, b, c), (x, y, z), cap, clearance, goal.close, lean)
