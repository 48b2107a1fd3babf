"""The kinds of motion a plan request asks for: their base class and their union.

Each kind is a member of :data:`MOTIONS`, told apart by its ``kind`` field and served by
its own planner (:data:`services.planner.registry.PLANNERS`): the via-point path in
:mod:`schemas.planning`, the goals a planner finds its own way to in
:mod:`schemas.goals`.
"""

from __future__ import annotations

from dataclasses import dataclass

from schemas.base import Message
from schemas.tagged import TaggedUnion


@dataclass(frozen=True)
class Motion(Message):
    """What a plan request asks for: one of the kinds in :data:`MOTIONS`.

    The base of the kinds of motion; each is told apart by its ``kind`` field and served by
    its own planner.
    """


MOTIONS: TaggedUnion[Motion] = TaggedUnion(Motion)
"""The kinds of motion the planner serves, by ``kind`` (``PlanRequest.motion``)."""
