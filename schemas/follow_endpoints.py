"""The endpoints of following a moving target (docs/follow.md), a block of their own in
the table of endpoints (:mod:`schemas.endpoints`, which re-exports them)."""

from __future__ import annotations

from schemas import control, follow, target
from schemas.endpoint import Audience, Service
from schemas.endpoint import publication as _pub
from schemas.endpoint import queryable as _query

TARGET = _pub(
    "target/pose",
    Service.SIMULATOR,
    target.TargetPose,
    "a tracker's target at 5-30 Hz (the user's mouth; the pose of the head it moves with): "
    "the simulated tracker's, until a tracker node of its own takes this key (and its "
    "ownership)",
    Audience.SUPERVISOR,
)
FOLLOW = _query(
    "controller/follow",
    Service.CONTROLLER,
    follow.FollowGoal,
    control.GoalAck,
    "follow a tracker's target to a standoff and hold it there, or stop following",
    Audience.SUPERVISOR,
)
FOLLOW_STATE = _pub(
    "controller/follow_state",
    Service.CONTROLLER,
    follow.FollowState,
    "the follow goal every cycle while it runs (target, predicted target, standoff point, "
    "tracked point), once when it ends",
    Audience.SUPERVISOR,
)
TARGET_TAKEN = _pub(
    "controller/target_taken",
    Service.CONTROLLER,
    target.TargetTaken,
    "each target frame as the controller took it: after which joint state (exact replays)",
)
FOLLOW_ENDPOINTS = (TARGET, FOLLOW, FOLLOW_STATE, TARGET_TAKEN)
"""The endpoints of following a target (a block of their own in
:data:`schemas.endpoints.TABLE`)."""
