"""The registry of command sources: what may drive the arm, one line each.

Each entry is a :class:`~services.controller.command_source.CommandSource` class; the
controller core holds one of each (:meth:`ControllerCore.source`) and its wiring map
(:mod:`.wiring`) takes their inputs and answers from here. Their ranks
(``PRIORITY``) decide who holds the arm, not their order here.
"""

from __future__ import annotations

from services.controller.command_source import CommandSource
from services.controller.follow_source import FollowSource
from services.controller.goal_source import GoalSource
from services.controller.jog import JogSource

SOURCES: tuple[type[CommandSource], ...] = (
    GoalSource,  # trajectory and gripper goals (controller/goal, controller/gripper)
    JogSource,  # live control (jog)
    FollowSource,  # following a moving target (controller/follow, target/pose)
)
"""Every command source of the controller."""
