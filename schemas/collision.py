"""Clearances between the arm and what is around it (``manus.collision``, ``manus.scene``).

A clearance names the arm body (``gripper``, ``forearm``, ...), what it was kept from (a
scene object, a zone or another arm body), the class whose clearance applies
(``person``, ``chair``, ``environment``, ``self``, ``zone``), the distance and the
clearance that class requires. Planners, the controller's guard and the simulator's
truth all report it in this one form.
"""

from __future__ import annotations

from dataclasses import dataclass

from schemas.base import Message, field

CLEARANCE_CLASSES = ("person", "chair", "environment", "self", "zone")


@dataclass(frozen=True)
class ClearanceReport(Message):
    """The tightest clearance of a trajectory, a run or a configuration."""

    TYPE_NAME = "manus/ClearanceReport/1"

    distance: float = field(
        "distance between the body and the object (a keep-in zone: to its boundary)", unit="m"
    )
    required: float = field("clearance its class requires", unit="m", minimum=0.0)
    body: str = field("the arm body (column, shoulder, upper_arm, forearm, wrist, gripper, ...)")
    other: str = field("the scene object, zone or arm body")
    cls: str = field("class whose clearance applies", choices=CLEARANCE_CLASSES)
    time: float = field("when: trajectory time, or stamp time for a run", unit="s", default=0.0)


@dataclass(frozen=True)
class SceneUpdate(Message):
    """Replace the planner's scene at run time (a table moved, a cup added): the whole
    scene, in the scene file format (docs/scene.md), validated whole before it is used."""

    TYPE_NAME = "manus/SceneUpdate/1"

    text: str = field("the scene file's YAML text")
    source: str = field("a name for it in messages (e.g. the file it came from)", default="")
    base_version: int = field(
        "the version this update replaces; refused when the current one differs "
        "(-1: whichever is current)",
        default=-1,
        minimum=-1,
    )


@dataclass(frozen=True)
class SceneReply(Message):
    """The planner's answer to a :class:`SceneUpdate`."""

    TYPE_NAME = "manus/SceneReply/1"

    accepted: bool = field("the scene is in use from the next plan on")
    version: int = field(
        "the version now in use (every plan reports the version it was checked against)",
        minimum=0,
    )
    error: str = field(
        "why it was refused: one line naming the source, line and field ('': accepted)",
        default="",
    )


@dataclass(frozen=True)
class SceneState(Message):
    """The scene the planner checks against, published when a :class:`SceneUpdate`
    replaces it and every second (version 0: the file read at start), so that the
    controller's guard and the sequencer's fold check follow, also after a restart."""

    TYPE_NAME = "manus/SceneState/1"

    version: int = field("its version (the one every plan reports)", minimum=0)
    text: str = field("the scene file's YAML text")
    source: str = field("its name in messages", default="")

    def same_scene(self, other: SceneState | None) -> bool:
        """Whether ``other`` is this scene (version and text; the name may differ between
        computers)."""
        return other is not None and (self.version, self.text) == (other.version, other.text)
