"""The simulator's sensors on the bus: the camera (:mod:`.camera`, ``perception/objects``)
and the moving target's tracker (:mod:`.target`, ``target/pose``), each stepped by the
core (:class:`~services.simulator.core.SimCore`) at its own instants; and the target's
body (the user's head), placed in the true distances at every tick so that they see the
person move. Functions of the core's camera and target (either may be off: None), so
that what the core holds is what they step.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from schemas import endpoints as ep
from schemas.base import Message
from services.simulator.camera import Camera
from services.simulator.contact import ContactModel
from services.simulator.objects import SimObject
from services.simulator.rays import Primitive
from services.simulator.target import MovingTarget

Seen = Callable[[int], tuple[list[tuple[SimObject, np.ndarray]], list[Primitive]]]
"""What the camera sees at a time [ns]: the objects at their poses, the arm's bodies."""


def next_event_ns(camera: Camera | None, target: MovingTarget | None) -> int | None:
    """The next capture or publication of the camera or the target's tracker [ns] (None:
    both off)."""
    # Asked several times a tick (:meth:`~services.simulator.core.SimCore.advance`): no
    # list, no generator, for the one or two that are on.
    if target is None:
        return None if camera is None else camera.next_event_ns()
    if camera is None:
        return target.next_event_ns()
    return min(camera.next_event_ns(), target.next_event_ns())


def event(
    camera: Camera | None, target: MovingTarget | None, t: int, seen: Seen
) -> list[tuple[int, str, Message]]:
    """What happens at ``t`` [ns] (an instant of :func:`next_event_ns`): the camera's
    capture of what ``seen(t)`` gives, and the publications due then: (publication time
    [ns], key suffix, message)."""
    out: list[tuple[int, str, Message]] = []
    if camera is not None and t == camera.next_event_ns():
        if t >= camera.next_capture_ns:
            camera.capture(t, *seen(t))
        out += [(at, ep.PERCEPTION, msg) for at, msg in camera.due(t)]
    if target is not None and t == target.next_event_ns():
        out += [(at, ep.TARGET, msg) for at, msg in target.due(t)]
    return out


def place_body(target: MovingTarget | None, contacts: ContactModel, t: int) -> None:
    """The target's body (the user's head) where it is at ``t`` [ns], in ``contacts``."""
    if target is not None and target.body_rest is not None:
        pose = target.body_pose(t)
        assert pose is not None
        contacts.move(target.config.body, pose)
