"""The simulator's configuration: every model number in one frozen, validated dataclass.

Layers: defaults < JSON file (``--config`` or ``$MANUS_SIM_CONFIG``) < command
line (``--seed``). File keys are the field names below (units in the names); ``arm`` takes
:meth:`manus.config.ArmConfig.from_mapping` keys (mm, deg) and ``faults`` the families of
:class:`services.simulator.faults.FaultConfig`. Unknown keys are an error.

Timeline constants (60 ms cycle, frames at +20/+40/+60 ms, 20 ms ticks and reply window)
are the protocol's (:mod:`manus.protocol`), not settings.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from manus.config import (
    FOLDED_Q_DEG,
    UNFOLDED_Q_DEG,
    ArmConfig,
    load_arm_config,
    read_json_object,
)
from manus.errors import ConfigError
from services.simulator.camera_config import CameraConfig
from services.simulator.faults import FaultConfig
from services.simulator.target_config import NO_TARGET, TargetConfig

TICK_MS = 20.0
"""Motion integration step and frame spacing [ms] (:data:`manus.protocol.TICK_S`)."""
MS = 1_000_000
"""One millisecond [ns] (simulator time is in integer nanoseconds)."""

START_POSES = ("folded", "unfolded")
GARBAGE_KINDS = ("noise", "max")


def _finite(name: str, value: float, lo: float, hi: float) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value) and lo <= value <= hi):
        raise ConfigError(f"`{name}` must be in [{lo:g}, {hi:g}], got {value!r}")


def _six(name: str, values: tuple[float, ...]) -> None:
    if len(values) != 6 or not all(math.isfinite(float(v)) for v in values):
        raise ConfigError(f"`{name}` must hold 6 finite numbers [deg], got {values!r}")


@dataclass(frozen=True)
class SimConfig:
    """Every parameter of the simulated arm.

    Attributes:
        seed: seed of every random choice (gain errors, garbage fields, faults).
        arm: geometry and joint limits (DH, SI units) shared with the rest of the stack.
        start_pose: ``folded`` (default, as after power-up in the wheelchair), ``unfolded``,
            or six DH joint angles [deg].
        start_gripper_mm: gripper opening at power-up [mm].
        folded_q_deg: pose the fold-in procedure (0x376) drives to, DH [deg].
        unfolded_q_deg: pose the fold-out procedure (0x375) drives to, DH [deg].
        fold_speed_deg_s: motor speed of the joint with the longest way in a fold
            procedure; the others are slower so that all arrive together [deg/s].
        transient_tau_ms: time constant of the first-order lag from commanded to actual
            motor speed (95 % after 3 tau) [ms].
        speed_gain_error: bound of the per-joint speed gain error (the arm's imperfect
            internal PI loop); each joint's gain is 1 + uniform(-e, e), seeded [-].
        first_motion_delay_ms: the first motion after power-up starts this late; a
            multiple of the 20 ms tick [ms].
        backlash_deg: full dead band of each joint's belt, joints 1..6 [deg].
        joint1_scale_error: joint 1 turns (1 + this) times its motor's motion from the
            power-up pose (where the absolute angles are right) [-].
        stale_encoders_deg: what the joint 4-6 fields report until ``stale_duration_ms``
            after the first command moving joints 4-6 (docs/protocol.md, Thesis stale
            encoders) [deg].
        stale_duration_ms: see ``stale_encoders_deg`` [ms].
        gripper_ready_ms: time of the general message "gripper ready" [ms].
        angles_measured_ms: time of "absolute angles measured"; no motion command is
            obeyed before it [ms].
        garbage: what position fields carry before a move mode is active: ``noise``
            (seeded random 16-bit values) or ``max`` (0x7FFF).
        faults: injected faults (none by default).
        scene: what is around the arm (:func:`manus.scene.scene_from_setting`: ``""`` =
            ``$MANUS_SCENE`` or the shipped wheelchair scene, ``default``, ``none`` or a
            scene file), the same as the planner's by default. A body
            that meets an object stops there (warning 3); the truth reports distances.
        objects: the objects the simulator holds at power-up (docs/objects.md): ``""`` =
            ``$MANUS_OBJECTS`` or none, ``default`` (a cup, a bottle and a phone on the
            shipped scene's table), ``none`` or an objects file.
        grasp_tolerance_mm: a grasp holds when the object's centre is within this of the
            grasp point across the jaw axis, else it slips [mm].
        camera: the simulated camera (:class:`~services.simulator.camera_config.CameraConfig`).
        target: a moving target and its tracker (the user's mouth; off by default:
            :class:`~services.simulator.target_config.TargetConfig`).
    """

    seed: int = 0
    arm: ArmConfig = field(default_factory=ArmConfig)
    start_pose: str | tuple[float, ...] = "folded"
    start_gripper_mm: float = 0.0
    folded_q_deg: tuple[float, ...] = FOLDED_Q_DEG
    unfolded_q_deg: tuple[float, ...] = UNFOLDED_Q_DEG
    fold_speed_deg_s: float = 15.0
    transient_tau_ms: float = 20.0
    speed_gain_error: float = 0.015
    first_motion_delay_ms: float = 60.0
    backlash_deg: tuple[float, ...] = (0.15, 0.05, 0.05, 0.3, 0.3, 0.3)
    joint1_scale_error: float = 0.003
    stale_encoders_deg: tuple[float, ...] = (179.3, -36.8, 82.6)
    stale_duration_ms: float = 240.0
    gripper_ready_ms: float = 300.0
    angles_measured_ms: float = 600.0
    garbage: str = "noise"
    faults: FaultConfig = field(default_factory=FaultConfig)
    scene: str = ""
    objects: str = ""
    grasp_tolerance_mm: float = 15.0
    camera: CameraConfig = field(default_factory=CameraConfig)
    target: TargetConfig = NO_TARGET

    def __post_init__(self) -> None:
        if not isinstance(self.seed, int) or self.seed < 0:
            raise ConfigError(f"`seed` must be a non-negative integer, got {self.seed!r}")
        if isinstance(self.start_pose, str):
            if self.start_pose not in START_POSES:
                raise ConfigError(
                    f"`start_pose` {self.start_pose!r} must be one of {START_POSES} "
                    "or six DH angles [deg]"
                )
        else:
            object.__setattr__(self, "start_pose", tuple(float(v) for v in self.start_pose))
            _six("start_pose", self.start_pose)
        for name in ("folded_q_deg", "unfolded_q_deg", "backlash_deg"):
            object.__setattr__(self, name, tuple(float(v) for v in getattr(self, name)))
            _six(name, getattr(self, name))
        if any(b < 0.0 or b > 10.0 for b in self.backlash_deg):
            raise ConfigError(f"`backlash_deg` values must be in [0, 10] deg: {self.backlash_deg}")
        gripper_max = self.arm.gripper_max * 1000.0
        _finite("start_gripper_mm", self.start_gripper_mm, 0.0, gripper_max)
        _finite("fold_speed_deg_s", self.fold_speed_deg_s, 0.1, 50.0)
        _finite("transient_tau_ms", self.transient_tau_ms, 0.0, 1000.0)
        _finite("speed_gain_error", self.speed_gain_error, 0.0, 0.5)
        _finite("first_motion_delay_ms", self.first_motion_delay_ms, 0.0, 10_000.0)
        if not math.isclose(
            self.first_motion_delay_ms / TICK_MS, round(self.first_motion_delay_ms / TICK_MS)
        ):
            raise ConfigError(
                f"`first_motion_delay_ms` {self.first_motion_delay_ms!r} must be a multiple "
                f"of the {TICK_MS:g} ms tick"
            )
        _finite("joint1_scale_error", self.joint1_scale_error, -0.1, 0.1)
        object.__setattr__(self, "stale_encoders_deg", tuple(map(float, self.stale_encoders_deg)))
        if len(self.stale_encoders_deg) != 3:
            raise ConfigError(f"`stale_encoders_deg` needs 3 values, got {self.stale_encoders_deg}")
        _finite("stale_duration_ms", self.stale_duration_ms, 0.0, 60_000.0)
        _finite("gripper_ready_ms", self.gripper_ready_ms, 0.0, 60_000.0)
        _finite("angles_measured_ms", self.angles_measured_ms, self.gripper_ready_ms, 60_000.0)
        _finite("grasp_tolerance_mm", self.grasp_tolerance_mm, 0.0, 100.0)
        if self.garbage not in GARBAGE_KINDS:
            raise ConfigError(f"`garbage` {self.garbage!r} must be one of {GARBAGE_KINDS}")
        q = self.start_q_deg
        lo, hi = np.degrees(self.arm.lower_array), np.degrees(self.arm.upper_array)
        for name, pose in (
            ("start pose", q),
            ("folded_q_deg", self.folded_q_deg),
            ("unfolded_q_deg", self.unfolded_q_deg),
        ):
            for j, (v, a, b) in enumerate(zip(pose, lo, hi, strict=True), start=1):
                if not a <= v <= b:
                    raise ConfigError(
                        f"{name}: joint {j} at {v:.1f} deg is outside its limits "
                        f"[{a:.1f}, {b:.1f}] deg"
                    )

    @property
    def start_q_deg(self) -> tuple[float, ...]:
        """The DH joint angles at power-up [deg]."""
        if self.start_pose == "folded":
            return self.folded_q_deg
        if self.start_pose == "unfolded":
            return self.unfolded_q_deg
        assert not isinstance(self.start_pose, str)
        return self.start_pose

    @classmethod
    def from_mapping(
        cls, data: dict[str, Any], *, source: str = "<mapping>", arm: ArmConfig | None = None
    ) -> SimConfig:
        """Build from JSON-like data (see the module docstring); ``arm``: the arm when the
        data has none.

        Raises:
            ConfigError: naming the source and the key.
        """
        known = {f.name for f in fields(cls)}
        kwargs: dict[str, Any] = {} if arm is None else {"arm": arm}
        for key, value in data.items():
            if key not in known:
                raise ConfigError(f"{source}: unknown simulator setting `{key}` ({sorted(known)})")
            nested = _NESTED.get(key)
            if nested is not None:
                if not isinstance(value, dict):
                    raise ConfigError(f"{source}: `{key}` must be an object")
                kwargs[key] = nested(value, source)
            elif isinstance(value, list):
                kwargs[key] = tuple(value)
            else:
                kwargs[key] = value
        try:
            return cls(**kwargs)
        except (TypeError, ValueError) as exc:
            raise ConfigError(f"{source}: {exc}") from exc

    def with_overrides(self, **changes: Any) -> SimConfig:
        """A copy with some fields replaced (validated again)."""
        return replace(self, **changes)


def load_sim_config(
    path: str | os.PathLike[str] | None = None,
    *,
    seed: int | None = None,
    arm_config: str | os.PathLike[str] | None = None,
) -> SimConfig:
    """Defaults < the arm configuration every service reads (``arm_config`` or
    ``$MANUS_ARM_CONFIG``, :func:`manus.config.load_arm_config`) < JSON file (``path`` or
    ``$MANUS_SIM_CONFIG``; its ``arm`` simulates an arm other than the one the stack
    models, for model-error tests) < ``seed``.

    Raises:
        ConfigError: a file cannot be read, is not JSON, or holds a bad setting.
    """
    chosen = path if path is not None else os.environ.get("MANUS_SIM_CONFIG")
    config = SimConfig(arm=load_arm_config(arm_config))
    if chosen:
        file = Path(chosen)
        data = read_json_object(file, "simulator config")
        config = SimConfig.from_mapping(data, source=str(file), arm=config.arm)
    if seed is not None:
        config = config.with_overrides(seed=seed)
    return config


_NESTED: dict[str, Any] = {
    "arm": lambda value, source: ArmConfig.from_mapping(value, source=f"{source}: arm"),
    "camera": lambda value, source: CameraConfig.from_mapping(value, source=f"{source}: camera"),
    "target": lambda value, source: TargetConfig.from_mapping(value, source=source),
    "faults": lambda value, source: FaultConfig.from_mapping(value, source=source),
}
"""The settings that are objects of their own, and how each is read (value, source)."""
