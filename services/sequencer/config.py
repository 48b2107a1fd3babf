"""Settings of the sequencer (frozen, validated at construction)."""

from __future__ import annotations

from dataclasses import dataclass, field

from manus.config import DEFAULT_ARM, ArmConfig
from manus.errors import ConfigError

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
    """

    arm: ArmConfig = field(default_factory=lambda: DEFAULT_ARM)
    required_services: tuple[str, ...] = REQUIRED_SERVICES
    result_margin_s: float = 10.0
    gripper_timeout_s: float = 30.0
    fold_timeout_s: float = 60.0
    cancel_timeout_s: float = 3.0
    progress_step: float = 0.02

    def __post_init__(self) -> None:
        for name in ("result_margin_s", "gripper_timeout_s", "fold_timeout_s", "cancel_timeout_s"):
            value = getattr(self, name)
            if not 0.1 <= value <= 3600.0:
                raise ConfigError(f"sequencer {name} = {value!r} s is outside 0.1..3600 s")
        if not 0.0 < self.progress_step <= 1.0:
            raise ConfigError(f"sequencer progress_step = {self.progress_step!r} outside (0, 1]")
