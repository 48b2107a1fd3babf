"""The world model at run time: the objects perception reports, kept as versioned diffs.

A deterministic core (no clock, no threads): :meth:`WorldModel.observe` takes a
:class:`~schemas.objects.Perception` (one frame of a perception source) and returns the
:class:`~schemas.objects.WorldUpdate` messages to publish. Every change is a diff from
the version before it, applied by :func:`manus.world_follower.apply_update`, the same
function a follower uses, so the diffs rebuild the model's set exactly; the whole set goes out every
``full_every_ms`` (judged on the frames' stamps) for followers that start late or missed
a diff (MoveIt's planning scene does the same with its diffs and full scenes).

Rules (docs/objects.md):

- an observation adds or moves its object; one older than the object's last observation
  is ignored; ``removed`` removes;
- an object not observed for more than ``stale_after_s`` is stale: marked so in the
  update of the first frame that finds it so, and judged again at any later time by
  :meth:`WorldModel.age_s` and :meth:`WorldModel.stale_reason` (a plan to it is refused
  naming its age, on the planner's own clock: its newest joint state);
- an observation farther from the last one than ``max_speed`` times the interval plus
  ``jump_tolerance`` is a jump: kept (perception is the stack's only view of the world)
  and reported in the update (:class:`~schemas.objects.ObjectJump`);
- a malformed perception message is refused whole and nothing changes; the refusal is
  counted and named in the next update;
- :meth:`WorldModel.attach` moves an object from the world to a link of the arm (its
  pose then in the link's frame, with the arm bodies and scene objects it may touch),
  :meth:`WorldModel.detach` back into the world where it is, each a diff like any other
  (MoveIt's attached objects). An attached object is the arm's: perception neither
  moves it nor removes it, and it is never stale; once detached, its stamp is the
  release's, so a frame captured before the release does not move it back.

The model's time is the newest frame stamp it has seen: its updates depend on the
perception stream alone, so a replay of a recording reproduces them whatever the other
streams did meanwhile. Frames stop coming (perception lost): nothing is published, and
the ages grow on a follower's own clock (``stamp_ns`` of each object; the stamps are the
computers' synchronised clocks live, the simulated clock in lock-step).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from manus.errors import ConfigError
from manus.orientation import matrix_to_ypr, pose_matrix
from manus.world_follower import FULL, WorldError, apply_update
from schemas.objects import (
    SIZE_COUNTS,
    ObjectJump,
    ObjectShape,
    Perception,
    WorldObject,
    WorldUpdate,
)

ARM = "arm"
"""``WorldObject.source`` of an object attached or detached since its last observation."""


@dataclass(frozen=True)
class WorldConfig:
    """How the world model judges observations.

    Attributes:
        stale_after_s: an object not observed for longer than this is stale [s].
        max_speed: the fastest an object can move (a hand moving it) [m/s].
        jump_tolerance: what perception noise may add to that between two observations [m].
        full_every_ms: how often the whole set goes out, judged on the stamps [ms].
        max_objects: most objects the model keeps; an observation of one more is refused.
    """

    stale_after_s: float = 2.0
    max_speed: float = 1.0
    jump_tolerance: float = 0.03
    full_every_ms: float = 1000.0
    max_objects: int = 64

    def __post_init__(self) -> None:
        for name, lo, hi in (
            ("stale_after_s", 0.01, 3600.0),
            ("max_speed", 0.0, 100.0),
            ("jump_tolerance", 0.0, 10.0),
            ("full_every_ms", 10.0, 60_000.0),
        ):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and lo <= value <= hi):
                raise ConfigError(
                    f"world model: `{name}` must be in [{lo:g}, {hi:g}], got {value!r}"
                )
        if not 1 <= self.max_objects <= 10_000:
            raise ConfigError(
                f"world model: `max_objects` must be in [1, 10000], got {self.max_objects!r}"
            )


def _name_ok(text: str) -> bool:
    return bool(text) and len(text) <= 64 and text.replace("_", "").replace("-", "").isalnum()


def check_perception(msg: Perception, max_objects: int = 10_000) -> None:
    """Refuse a malformed perception message whole.

    Raises:
        WorldError: naming the source, the frame, the field and the value.
    """
    where = f"perception from {msg.source or '?'!r} frame {msg.seq}"
    if not _name_ok(msg.source):
        raise WorldError(f"{where}: source must be a name (letters, digits, _ and -)")
    seen: set[str] = set()
    for i, obj in enumerate(msg.objects):
        path = f"{where}: objects[{i}]"
        if not _name_ok(obj.id):
            raise WorldError(f"{path}.id: {obj.id!r} is not a name (letters, digits, _ and -)")
        if obj.id in seen:
            raise WorldError(f"{path}.id: {obj.id!r} is given twice")
        seen.add(obj.id)
        if not _name_ok(obj.cls):
            raise WorldError(f"{path}.cls: {obj.cls!r} is not a name (letters, digits, _ and -)")
        wanted = SIZE_COUNTS[ObjectShape(obj.shape)]
        if len(obj.size) != wanted:
            raise WorldError(
                f"{path}.size: a {obj.shape} takes {wanted} value(s), got {len(obj.size)}"
            )
        if not all(0.0 < v <= 10.0 for v in obj.size):
            raise WorldError(f"{path}.size: every value must be in (0, 10] m, got {obj.size}")
        if not all(abs(v) <= 100.0 for v in obj.xyz):
            raise WorldError(f"{path}.xyz: {obj.xyz} is more than 100 m from the chair")
    both = seen.intersection(msg.removed)
    if both:
        raise WorldError(f"{where}: {sorted(both)} both seen and removed")
    if len(msg.objects) > max_objects:
        raise WorldError(f"{where}: {len(msg.objects)} objects, at most {max_objects}")


class WorldModel:
    """The objects, their versions and their ages (see the module docstring).

    Args:
        config: stale time, jump rule and the whole set's period.
    """

    def __init__(self, config: WorldConfig | None = None) -> None:
        self.config = config or WorldConfig()
        self.objects: dict[str, WorldObject] = {}
        """The objects by id, as the last update left them."""
        self.version = 0
        self.now_ns: int | None = None
        """The model's time: the newest frame stamp seen [ns] (None: none yet)."""
        self.refused = 0
        self.error = ""
        self.jumps = 0
        """Jumps seen since start."""
        self._full_ns: int | None = None

    # -- inputs -----------------------------------------------------------------------------

    def observe(self, msg: Perception) -> list[WorldUpdate]:
        """Take one perception frame: the diff it makes (and the whole set when due).

        A malformed message is refused whole (:func:`check_perception`): counted, named in
        :attr:`error`, nothing changes and nothing is published for it.
        """
        try:
            check_perception(msg, self.config.max_objects)
            self._check_room(msg)
        except WorldError as exc:
            self.refused += 1
            self.error = str(exc)
            return []
        self._advance(msg.stamp_ns)
        changed: dict[str, WorldObject] = {}
        jumps: list[ObjectJump] = []
        for seen in msg.objects:
            old = self.objects.get(seen.id)
            if old is not None and (msg.stamp_ns < old.stamp_ns or old.link):
                continue  # an older frame than the one it was last seen in, or held
            new = WorldObject(
                id=seen.id,
                cls=seen.cls,
                shape=seen.shape,
                size=list(seen.size),
                xyz=list(seen.xyz),
                ypr=list(seen.ypr),
                confidence=seen.confidence,
                stamp_ns=msg.stamp_ns,
                source=msg.source,
                stale=self._is_stale(msg.stamp_ns),
            )
            if old is not None:
                jump = self._jump(old, new)
                if jump is not None:
                    jumps.append(jump)
            changed[new.id] = new
        removed = [
            name
            for name in dict.fromkeys(msg.removed)
            if name in self.objects and not self.objects[name].link
        ]
        changed.update(self._staling(exclude={*changed, *removed}))
        return self._emit(list(changed.values()), removed, jumps)

    def attach(
        self,
        object_id: str,
        link: str,
        grip: np.ndarray,
        stamp_ns: int,
        touch_links: Sequence[str],
        touch_objects: Sequence[str] = (),
    ) -> list[WorldUpdate]:
        """Attach ``object_id`` to ``link`` at ``grip`` (its pose in the link's frame,
        (4, 4)) from ``stamp_ns`` on (the time of the grasp), with the arm bodies and
        scene objects it may touch; attached already to ``link``: held anew. Returns the
        diff (and the whole set when due).

        Raises:
            WorldError: no such object, or attached to another link.
        """
        obj = self._get(object_id)
        if obj.link and obj.link != link:
            raise WorldError(f"object {object_id!r} is attached to {obj.link!r}: detach it first")
        return self._place(obj, grip, stamp_ns, link, list(touch_links), list(touch_objects))

    def detach(self, object_id: str, pose: np.ndarray, stamp_ns: int) -> list[WorldUpdate]:
        """Put the attached ``object_id`` back into the world at ``pose`` (chair frame,
        (4, 4)) from ``stamp_ns`` on (the time of the release). Returns the diff.

        Raises:
            WorldError: no such object, or not attached.
        """
        obj = self._get(object_id)
        if not obj.link:
            raise WorldError(f"object {object_id!r} is not attached to the arm")
        return self._place(obj, pose, stamp_ns, "", [], [])

    def _place(
        self,
        obj: WorldObject,
        pose: np.ndarray,
        stamp_ns: int,
        link: str,
        touch_links: list[str],
        touch_objects: list[str],
    ) -> list[WorldUpdate]:
        self._advance(stamp_ns)
        placed = replace(
            obj,
            xyz=[float(v) for v in pose[:3, 3]],
            ypr=list(matrix_to_ypr(pose[:3, :3])),
            stamp_ns=max(stamp_ns, obj.stamp_ns),
            source=ARM,
            stale=False,
            link=link,
            touch_links=touch_links,
            touch_objects=touch_objects,
        )
        return self._emit([placed], [], [])

    def pose(self, object_id: str) -> np.ndarray:
        """``object_id``'s pose (4, 4): in the chair frame, or attached, in its link's.

        Raises:
            WorldError: no such object.
        """
        obj = self._get(object_id)
        return pose_matrix(obj.xyz, (obj.ypr[0], obj.ypr[1], obj.ypr[2]))

    # -- readings -----------------------------------------------------------------------------

    def age_s(self, object_id: str, now_ns: int | None = None) -> float:
        """Time since ``object_id`` was last observed [s], at ``now_ns`` (default, or when
        earlier: the newest frame's stamp).

        Raises:
            WorldError: no such object.
        """
        obj = self._get(object_id)
        assert self.now_ns is not None  # an object exists: a frame was seen
        now = self.now_ns if now_ns is None else max(now_ns, self.now_ns)
        return max(0.0, (now - obj.stamp_ns) / 1e9)

    def stale_reason(self, object_id: str, now_ns: int | None = None) -> str:
        """Why a plan to ``object_id`` is refused at ``now_ns`` ('' when it is fresh or
        attached): its age, who saw it last and the limit.

        Raises:
            WorldError: no such object.
        """
        obj = self._get(object_id)
        age = self.age_s(object_id, now_ns)
        if age <= self.config.stale_after_s or obj.link:
            return ""
        return (
            f"object {object_id!r} ({obj.cls}) was last observed {age:.1f} s ago by "
            f"{obj.source} (stale after {self.config.stale_after_s:g} s)"
        )

    def full(self) -> WorldUpdate:
        """The whole set at the current version."""
        return WorldUpdate(
            stamp_ns=self.now_ns or 0,
            version=self.version,
            base_version=FULL,
            objects=list(self.objects.values()),
            refused=self.refused,
            error=self.error,
            stale_after_s=self.config.stale_after_s,
        )

    # -- the rules ------------------------------------------------------------------------------

    def _get(self, object_id: str) -> WorldObject:
        obj = self.objects.get(object_id)
        if obj is None:
            known = ", ".join(sorted(self.objects)) or "none"
            raise WorldError(f"no object {object_id!r} in the world model (known: {known})")
        return obj

    def _check_room(self, msg: Perception) -> None:
        new = {o.id for o in msg.objects} - set(self.objects)
        room = (
            self.config.max_objects - len(self.objects) + len(set(msg.removed) & set(self.objects))
        )
        if len(new) > room:
            raise WorldError(
                f"perception from {msg.source!r} frame {msg.seq}: {len(new)} new objects, "
                f"room for {max(room, 0)} (max_objects {self.config.max_objects})"
            )

    def _advance(self, stamp_ns: int) -> None:
        if self.now_ns is None or stamp_ns > self.now_ns:
            self.now_ns = stamp_ns

    def _is_stale(self, stamp_ns: int) -> bool:
        assert self.now_ns is not None
        return (self.now_ns - stamp_ns) > self.config.stale_after_s * 1e9

    def _staling(self, exclude: set[str]) -> dict[str, WorldObject]:
        """Objects (but ``exclude``) that the clock made stale, not marked so yet."""
        return {
            o.id: replace(o, stale=True)
            for o in self.objects.values()
            if o.id not in exclude and not o.stale and not o.link and self._is_stale(o.stamp_ns)
        }

    def _jump(self, old: WorldObject, new: WorldObject) -> ObjectJump | None:
        interval = (new.stamp_ns - old.stamp_ns) / 1e9
        distance = math.dist(old.xyz, new.xyz)
        allowed = self.config.max_speed * interval + self.config.jump_tolerance
        if distance <= allowed:
            return None
        self.jumps += 1
        return ObjectJump(
            id=new.id, distance=distance, allowed=allowed, interval=interval, source=new.source
        )

    def _emit(
        self, changed: list[WorldObject], removed: list[str], jumps: list[ObjectJump]
    ) -> list[WorldUpdate]:
        out: list[WorldUpdate] = []
        now = self.now_ns or 0
        if changed or removed:
            diff = WorldUpdate(
                stamp_ns=now,
                version=self.version + 1,
                base_version=self.version,
                objects=changed,
                removed=removed,
                jumps=jumps,
                refused=self.refused,
                error=self.error,
                stale_after_s=self.config.stale_after_s,
            )
            self.objects = apply_update(self.objects, self.version, diff)
            self.version = diff.version
            out.append(diff)
        every_ns = round(self.config.full_every_ms * 1e6)
        if self._full_ns is None or now - self._full_ns >= every_ns or now < self._full_ns:
            self._full_ns = now
            out.append(self.full())
        return out
