"""Planner settings: the arm model and the margins the planner applies to it."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from manus.config import DEFAULT_ARM, ArmConfig
from manus.errors import ConfigError
from manus.world import WorldConfig


@dataclass(frozen=True)
class PlannerConfig:
    """How the planner judges a path.

    Attributes:
        arm: geometry, joint limits, speed and acceleration limits.
        max_knot_jump: largest move of any joint between two consecutive via points
            [rad]; a bigger one means the IK left the start's branch in effect (default
            90 deg).
        wrist_margin: closest the wrist (joint 5) may come to its singularity (q5 = 0 or
            pi) anywhere along the trajectory [rad] (default 2 deg).
        check_samples: samples per segment for the checks that have no closed form
            (the shoulder branch) [-].
        max_preview_points: most points in the Cartesian preview; longer trajectories
            (or finer steps asked for) get a coarser step [-].
        scene: the scene every trajectory is checked against
            (:func:`manus.scene.scene_from_setting`: ``""`` = ``$MANUS_SCENE`` or the
            shipped wheelchair scene, ``default``, ``none`` = no check, or a file).
        scene_every_ms: how often the scene in use is published on ``planner/scene_state``
            [ms], judged on the joint states' stamps (at the first one, then every so
            often), so that a controller or sequencer started (or restarted) after a
            run-time update, and a recording, learn it; 0: only when an update replaces it.
        world: the world model's rules (stale time, jumps; :mod:`manus.world`): the planner
            keeps the objects perception reports and publishes them on ``planner/objects``.
        resume_lead_s: time added to reach the first via point left when a paused path
            goes on [s]: the arm starts from rest (and the planner stretches more if the
            joint limits need it).
        padding: margin a goal plan keeps beyond every clearance away from its start and
            its end [m] (tracking errors and the sweep's resolution eat into it;
            docs/reach.md).
        poses: the user's named poses file (:mod:`manus.named_poses`: ``""`` =
            ``$MANUS_POSES``, else only the shipped poses).
    """

    arm: ArmConfig = field(default_factory=lambda: DEFAULT_ARM)
    max_knot_jump: float = math.radians(90.0)
    wrist_margin: float = math.radians(2.0)
    check_samples: int = 32
    max_preview_points: int = 2000
    scene: str = ""
    scene_every_ms: float = 1000.0
    world: WorldConfig = field(default_factory=WorldConfig)
    resume_lead_s: float = 0.6
    padding: float = 0.005
    poses: str = ""

    def __post_init__(self) -> None:
        if not (math.isfinite(self.resume_lead_s) and 0.0 <= self.resume_lead_s <= 60.0):
            raise ConfigError(f"`resume_lead_s` must be in [0, 60] s, got {self.resume_lead_s!r}")
        if not (math.isfinite(self.scene_every_ms) and 0.0 <= self.scene_every_ms <= 60_000.0):
            raise ConfigError(
                f"`scene_every_ms` must be in [0, 60000] ms, got {self.scene_every_ms!r}"
            )
        if not (math.isfinite(self.padding) and 0.0 <= self.padding <= 0.1):
            raise ConfigError(f"`padding` must be in [0, 0.1] m, got {self.padding!r}")
        if not 0.0 < self.max_knot_jump <= 2.0 * math.pi:
            raise ConfigError(
                f"`max_knot_jump` must be in (0, 2 pi] rad, got {self.max_knot_jump!r}"
            )
        if not 0.0 <= self.wrist_margin < math.pi / 2:
            raise ConfigError(f"`wrist_margin` must be in [0, pi/2) rad, got {self.wrist_margin!r}")
        if not 2 <= self.check_samples <= 10_000:
            raise ConfigError(f"`check_samples` must be in [2, 10000], got {self.check_samples!r}")
        if not 2 <= self.max_preview_points <= 1_000_000:
            raise ConfigError(
                f"`max_preview_points` must be in [2, 1000000], got {self.max_preview_points!r}"
            )
