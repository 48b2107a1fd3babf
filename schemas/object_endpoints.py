"""The objects' endpoints: perception and the world model (docs/objects.md), a block of
their own in the table of endpoints (:mod:`schemas.endpoints`, which re-exports them)."""

from __future__ import annotations

from schemas import objects
from schemas.endpoint import Audience, Service
from schemas.endpoint import publication as _pub
from schemas.endpoint import queryable as _query

PERCEPTION = _pub(
    "perception/objects",
    Service.SIMULATOR,
    objects.Perception,
    "one camera frame's objects (added or moved) and the ones known gone; the simulated "
    "camera's, until a perception node of its own takes this key (and its ownership)",
)
OBJECTS = _pub(
    "planner/objects",
    Service.PLANNER,
    objects.WorldUpdate,
    "the world model's objects as versioned diffs, and the whole set every second",
    Audience.SUPERVISOR,
)
ATTACH = _query(
    "planner/attach",
    Service.PLANNER,
    objects.AttachRequest,
    objects.AttachReply,
    "attach a grasped object to the gripper (part of the arm from then on) or detach a "
    "released one where it is: a diff on planner/objects",
    clients=(Service.SEQUENCER,),
)
OBJECT_ENDPOINTS = (PERCEPTION, OBJECTS, ATTACH)
"""The objects' endpoints (a block of their own in :data:`schemas.endpoints.TABLE`)."""
