"""Settings of the sequencer (frozen, validated at construction)."""

from __future__ import annotations

from dataclasses import dataclass, field

from manus.config import DEFAULT_ARM, ArmConfig
from manus.errors import ConfigError
from services.sequencer.pick_config import PickConfig

REQUIRED_SERVICES = ("planner", "controller", "can_bridge")
"""Services a task needs (liveliness names, ``schemas.keys.SERVICES``)."""


@dataclass(frozen=True)
class SequencerConfig:
    """How the sequencer runs tasks.

    Attributes:
        arm: arm geometry (forward kinematics of named poses and resumed paths).
        required_services: liveliness names that must be up to start a task.
        result_margin_s: time allowed past a goal's planned end (plus the goal's own
            ``goal_time_tolerance``) before the step fails for want of a result [s].
        gripper_timeout_s: time allowed to a gripper step [s].
        fold_timeout_s: time allowed to a fold [s].
        cancel_timeout_s: time allowed to the controller to confirm a cancel or pause
            (its bounded deceleration) before the sequencer asks the bridge to stop [s].
        progress_step: smallest change of a step's progress worth a ``step_progress``
            event (fraction, 0..1).
        heartbeat_timeout_s: the deadman of every move and gripper goal: the
            ``heartbeat_timeout`` of its controller goal [s] (0: none). While a task runs
            the sequencer answers each joint state with a ``Heartbeat`` echoing it; the
            controller stops the arm when the newest echo is older than this
            (docs/deployment.md, Faults). 0.15 s: one echo may come a cycle late. At 0.1 s
            every round trip had to come back within the cycle, and one that did not
            stopped a drink's fold move in CI (an echo 120 ms old, 2026-11-26, the rest in
            time); a hung sequencer or a silently cut link stops the arm one cycle (60 ms)
            later. A killed sequencer or a closed link stops it at once (its token).
        fold_heartbeat_timeout_s: the same deadman for folds, which the bridge drives
            (``ArmCommand.heartbeat_timeout``) [s] (0: none). 0.15 s, as a move's (seen in
            CI at a fold's start: echoes 119-144 ms old at load 3, every one in time a
            cycle later).
        link_timeout_s: no joint state for this long while a goal is active fails the task
            ("no joint states from the arm ...": the link to the arm computer is down) [s].
        history: how many ended tasks ``sequencer/history`` remembers.
        bridge_wait_s: how long a task submitted while the bridge is still starting
            waits for phase ``running`` and a valid joint state before it is refused [s]
            (0: refused at once; :mod:`services.sequencer.bridge_wait`).
        resync_wait_s: how long a goal the controller refused because the bridge was
            not ``running`` waits for it to run again, mid-task, before the task fails
            [s] (0: fails at once). A lost or late frame puts the bridge in ``resync``
            for two clean cycles (120 ms); a goal sent then, between two motions, is
            sent again once it runs (:class:`services.sequencer.goal_step.GoalStep`).
        scene: the scene folds are checked against (``""`` = ``$MANUS_SCENE`` or the
            shipped one, ``default``, ``none`` or a file; the planner checks every move
            against its own, the same by default).
        pick: the pick, place and give steps (:class:`PickConfig`).
    """

    arm: ArmConfig = field(default_factory=lambda: DEFAULT_ARM)
    required_services: tuple[str, ...] = REQUIRED_SERVICES
    result_margin_s: float = 10.0
    gripper_timeout_s: float = 30.0
    fold_timeout_s: float = 60.0
    cancel_timeout_s: float = 3.0
    progress_step: float = 0.02
    heartbeat_timeout_s: float = 0.15
    fold_heartbeat_timeout_s: float = 0.15
    link_timeout_s: float = 0.5
    history: int = 100
    bridge_wait_s: float = 30.0
    resync_wait_s: float = 1.0
    scene: str = ""
    pick: PickConfig = field(default_factory=PickConfig)

    def __post_init__(self) -> None:
        for name in ("result_margin_s", "gripper_timeout_s", "fold_timeout_s", "cancel_timeout_s"):
            value = getattr(self, name)
            if not 0.1 <= value <= 3600.0:
                raise ConfigError(f"sequencer {name} = {value!r} s is outside 0.1..3600 s")
        for name in ("heartbeat_timeout_s", "fold_heartbeat_timeout_s"):
            value = getattr(self, name)
            if not 0.0 <= value <= 10.0:
                raise ConfigError(
                    f"sequencer {name} = {value!r} s is outside 0..10 s (0: no deadman)"
                )
        if not 0.0 <= self.bridge_wait_s <= 3600.0:
            raise ConfigError(
                f"sequencer bridge_wait_s = {self.bridge_wait_s!r} s is outside 0..3600 s"
            )
        if not 1 <= self.history <= 10_000:
            raise ConfigError(f"sequencer history = {self.history!r} is outside 1..10000")
        if not 0.1 <= self.link_timeout_s <= 3600.0:
            raise ConfigError(
                f"sequencer link_timeout_s = {self.link_timeout_s!r} s is outside 0.1..3600 s"
            )
        if not 0.0 < self.progress_step <= 1.0:
            raise ConfigError(f"sequencer progress_step = {self.progress_step!r} outside (0, 1]")
