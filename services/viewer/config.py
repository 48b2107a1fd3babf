"""The viewer's settings and counters."""

from __future__ import annotations

from dataclasses import dataclass, field

from manus.config import DEFAULT_ARM, ArmConfig


@dataclass(frozen=True)
class ViewerConfig:
    """What the viewer draws and how much it keeps.

    Attributes:
        prefix: key prefix of the arm.
        arm: geometry (forward kinematics, URDF).
        path_points: most points kept of the executed and true paths.
        path_step_m: a new path point only after the gripper moved this far [m].
        path_every: publish a path after this many new points.
        preview_dt_s: sampling step [s] of a goal's path when it has no preview.
        scene: the scene drawn until the planner publishes another, as every service's
            ``scene`` setting (``""``: ``$MANUS_SCENE`` or the shipped one; ``default``;
            ``none``; a file: :func:`manus.scene.scene_from_setting`).
    """

    prefix: str = "manus"
    arm: ArmConfig = DEFAULT_ARM
    path_points: int = 3000
    path_step_m: float = 0.0005
    path_every: int = 3
    preview_dt_s: float = 0.05
    scene: str = ""

    def __post_init__(self) -> None:
        if self.path_points < 2 or self.path_every < 1:
            raise ValueError(
                f"path_points {self.path_points} must be >= 2 and path_every {self.path_every} >= 1"
            )
        if not (self.path_step_m >= 0 and self.preview_dt_s > 0):
            raise ValueError(
                f"path_step_m {self.path_step_m} must be >= 0 and preview_dt_s "
                f"{self.preview_dt_s} > 0 [m, s]"
            )


@dataclass
class ViewerStats:
    """Counters of the core.

    Attributes:
        inputs: samples received.
        outputs: Foxglove messages produced.
        bad_payloads: samples that did not decode, by key suffix.
        ignored: samples on keys the viewer does not draw.
    """

    inputs: int = 0
    outputs: int = 0
    bad_payloads: dict[str, int] = field(default_factory=dict)
    ignored: int = 0
