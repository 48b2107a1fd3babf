"""Following the world model (``planner/objects``): its versioned diffs and whole sets,
applied the one way every follower applies them.

The world model (:class:`manus.world.WorldModel`, run by the planner) publishes each
change as a :class:`~schemas.objects.WorldUpdate`: a diff from ``base_version``, or now
and then the whole set (``base_version`` :data:`FULL`). :func:`apply_update` applies one
(the model applies its own diffs with it too, so diffs and whole sets always agree);
:class:`WorldFollower` is what the controller, the sequencer and the viewer keep: the
objects at a version, and the bodies the arm holds among them
(:func:`manus.held.held_bodies`), which their collision models follow.
"""

from __future__ import annotations

from manus.errors import ManusError
from manus.held import HeldBody, HeldError, held_bodies
from schemas.objects import WorldObject, WorldUpdate

FULL = -1
"""``WorldUpdate.base_version`` of an update that carries the whole set."""


class WorldError(ManusError, ValueError):
    """A perception message the world model refuses, or a diff that does not apply."""


def apply_update(
    objects: dict[str, WorldObject], version: int, update: WorldUpdate
) -> dict[str, WorldObject]:
    """The object set after ``update`` (a new dict; ``objects`` is not changed).

    Args:
        objects: the set a follower holds, at ``version``.
        version: its version.
        update: a diff from ``version``, or a whole set (``base_version`` -1).

    Raises:
        WorldError: a diff from another version than ``version`` (wait for a whole set).
    """
    if update.base_version == FULL:
        return {o.id: o for o in update.objects}
    if update.base_version != version:
        raise WorldError(
            f"world update {update.version} applies to version {update.base_version}, but "
            f"version {version} is held: wait for the next whole set"
        )
    out = dict(objects)
    for name in update.removed:
        out.pop(name, None)
    for obj in update.objects:
        out[obj.id] = obj
    return out


class WorldFollower:
    """The world model as a follower holds it (see the module docstring)."""

    def __init__(self) -> None:
        self.objects: dict[str, WorldObject] = {}
        """The objects by id, at :attr:`version`."""
        self.version = 0
        self.held: tuple[HeldBody, ...] = ()
        """The bodies the arm holds, by id."""

    def on_update(self, update: WorldUpdate) -> bool:
        """Apply ``update``; returns whether the held bodies changed. A diff from another
        version than the one held (one was missed: the next whole set brings it), or an
        object held where none can be (another link), changes nothing."""
        try:
            objects = apply_update(self.objects, self.version, update)
            held = held_bodies(objects.values())
        except (WorldError, HeldError):
            return False
        self.objects, self.version = objects, update.version
        changed = held != self.held
        self.held = held
        return changed
