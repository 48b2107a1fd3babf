"""Jog settings: the deadman, the speed levels, the caps, the slow-down zones, drink mode."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from manus.errors import ConfigError
from manus.quantize import GRIPPER_COUNT_M_S, GRIPPER_COUNT_MAX
from schemas.jog import MAX_ANGULAR, MAX_GRIPPER, MAX_JOINT, MAX_LINEAR, JogCaps

DEG = math.pi / 180.0


def _check(name: str, value: float, lo: float, hi: float) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value) and lo <= value <= hi):
        raise ConfigError(f"jog: `{name}` must be in [{lo:g}, {hi:g}], got {value!r}")


@dataclass(frozen=True)
class JogConfig:
    """How the controller runs live control (``services/controller/jog.py``).

    Attributes:
        timeout_ms: deadman: a jog command older than this (judged on the joint states'
            stamps: a command is as old as the newest joint state before it) stops the
            arm [ms]. Ages are multiples of the 60 ms cycle, so 150 ms stops at the third
            joint state without a newer command: any gap up to 120 ms passes whatever its
            phase (10 Hz with +-20 ms of jitter), a gap over 180 ms never does.
        levels: number of speed levels (level ``levels`` runs at the caps).
        default_level: level at start.
        max_linear: Cartesian speed cap of the gripper origin at the top level [m/s]
            (at most 0.25, the reduced speed for robots working next to people).
        max_angular: angular speed cap at the top level [rad/s].
        max_joint: joint speed cap at the top level [rad/s] (at most the arm's 50 deg/s).
        max_gripper: gripper speed cap at the top level [m/s].
        linear_accel: ramp of the commanded linear speed [m/s^2].
        angular_accel: ramp of the commanded angular speed [rad/s^2].
        joint_accel: ramp of commanded joint speeds [rad/s^2].
        damping_m: damped least squares of the differential IK [m] (rotation rows in m
            through ``rotation_weight_m``); small: exact away from singularities.
        rotation_weight_m: weight of the rotation error against the position error in
            the differential IK [m/rad].
        wrist_slow_deg: the jog slows down when q5 comes closer than this to 0 or 180
            deg (the wrist singularity, q4 and q6 aligned) [deg] ...
        wrist_stop_deg: ... and stops this close [deg] (never a wrist flip).
        elbow_slow_deg: likewise for the elbow straightening (|q3 - 90 deg|) [deg] ...
        elbow_stop_deg: ... stopping this close [deg] (the arm refuses within 3 deg).
        limit_slow_deg: likewise for each joint approaching its limit [deg] ...
        limit_stop_deg: ... stopping this far from it [deg].
        rim_offset: drink mode: the point the cup pours about (its rim), in the gripper
            frame [m], shape (3,).
        reanchor_deg: the reference restarts from the arm's predicted position when they
            differ by more than this on any motor (the arm was held back) [deg].
    """

    timeout_ms: float = 150.0
    levels: int = 5
    default_level: int = 3
    max_linear: float = MAX_LINEAR
    max_angular: float = MAX_ANGULAR
    max_joint: float = MAX_JOINT
    max_gripper: float = MAX_GRIPPER
    linear_accel: float = 1.0
    angular_accel: float = 200.0 * DEG
    joint_accel: float = 200.0 * DEG
    damping_m: float = 1e-3
    rotation_weight_m: float = 0.2
    wrist_slow_deg: float = 20.0
    wrist_stop_deg: float = 5.0
    elbow_slow_deg: float = 20.0
    elbow_stop_deg: float = 6.0
    limit_slow_deg: float = 10.0
    limit_stop_deg: float = 1.0
    rim_offset: tuple[float, float, float] = field(default=(0.0, 0.0, 0.06))
    reanchor_deg: float = 1.0

    def __post_init__(self) -> None:
        _check("timeout_ms", self.timeout_ms, 20.0, 5000.0)
        if not isinstance(self.levels, int) or not 1 <= self.levels <= 20:
            raise ConfigError(f"jog: `levels` must be an integer in [1, 20], got {self.levels!r}")
        if not isinstance(self.default_level, int) or not 1 <= self.default_level <= self.levels:
            raise ConfigError(
                f"jog: `default_level` must be an integer in [1, {self.levels}], "
                f"got {self.default_level!r}"
            )
        _check("max_linear", self.max_linear, 0.001, 0.25)
        _check("max_angular", self.max_angular, 0.001, 90.0 * DEG)
        _check("max_joint", self.max_joint, 0.001, 50.0 * DEG + 1e-12)
        _check("max_gripper", self.max_gripper, 0.001, GRIPPER_COUNT_M_S * GRIPPER_COUNT_MAX)
        _check("linear_accel", self.linear_accel, 0.01, 100.0)
        _check("angular_accel", self.angular_accel, 0.01, 1000.0)
        _check("joint_accel", self.joint_accel, 0.01, 1000.0)
        _check("damping_m", self.damping_m, 0.0, 0.1)
        _check("rotation_weight_m", self.rotation_weight_m, 0.001, 10.0)
        for zone in ("wrist", "elbow", "limit"):
            stop, slow = getattr(self, f"{zone}_stop_deg"), getattr(self, f"{zone}_slow_deg")
            _check(f"{zone}_stop_deg", stop, 0.0, 80.0)
            _check(f"{zone}_slow_deg", slow, stop + 0.1, 89.0)
        if len(self.rim_offset) != 3:
            raise ConfigError(f"jog: `rim_offset` must hold 3 values [m], got {self.rim_offset!r}")
        for v in self.rim_offset:
            _check("rim_offset", v, -0.5, 0.5)
        object.__setattr__(self, "rim_offset", tuple(float(v) for v in self.rim_offset))
        _check("reanchor_deg", self.reanchor_deg, 0.05, 30.0)

    @property
    def timeout_ns(self) -> int:
        """The deadman's timeout [ns]."""
        return round(self.timeout_ms * 1e6)

    def share(self, level: int) -> float:
        """The caps' share at speed level ``level`` (1 at the top level)."""
        return level / self.levels

    def caps(self, level: int) -> JogCaps:
        """The caps at speed level ``level``."""
        k = self.share(level)
        return JogCaps(
            linear=self.max_linear * k,
            angular=self.max_angular * k,
            joints=self.max_joint * k,
            gripper=self.max_gripper * k,
        )
