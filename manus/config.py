"""Arm parameters: geometry, joint limits and speed limits.

All values are SI (m, rad, rad/s) inside the stack; the defaults are written in the
thesis's units (mm, deg) next to their conversion so they can be checked against
docs/protocol.md, The arm. Configuration layers defaults < file < environment < command line;
this module holds the defaults, the validation and the file layer.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any

import numpy as np

from manus.errors import ConfigError

DEG = math.pi / 180.0
"""One degree in radians."""

N_JOINTS = 6
"""Revolute joints of the Manus (the lift unit is not modelled: always 0)."""


def _default_lower() -> tuple[float, ...]:
    # Joint 5 (wrist pitch) has a finite range; the others may turn more than once
    # (docs/protocol.md, Limits): +-360 deg keeps a full turn available either way.
    return tuple(d * DEG for d in (-360.0, -360.0, -360.0, -360.0, -120.0, -360.0))


def _default_upper() -> tuple[float, ...]:
    return tuple(d * DEG for d in (360.0, 360.0, 360.0, 360.0, 120.0, 360.0))


def _default_speed() -> tuple[float, ...]:
    # 10 counts of 0.1 deg per 20 ms = 50 deg/s, the arm's fastest joint speed.
    return tuple(50.0 * DEG for _ in range(N_JOINTS))


@dataclass(frozen=True)
class ArmConfig:
    """Geometry and limits of one Manus arm.

    Attributes:
        l1: shoulder offset d_2 [m] (thesis 105 mm).
        l2: upper-arm length a_2 [m] (thesis 400 mm).
        l3: forearm length d_4 [m] (thesis 320 mm).
        l4: wrist centre to gripper frame d_6 [m] (thesis 160 mm).
        lower: lower joint limits in the DH frame [rad], shape (6,).
        upper: upper joint limits in the DH frame [rad], shape (6,).
        max_speed: per-joint speed limits [rad/s], shape (6,) (thesis: 5-50 deg/s).
        max_accel: per-joint acceleration limits used by trajectory checks [rad/s^2].
        gripper_max: largest gripper opening [m] (90 mm).
        singular_tol: |sin q5| below which the wrist counts as singular [-].
        work_floor_z: the arm's own work area: the gripper may not go below this z in
            the base frame [m] (the arm refuses with warning 1; docs/protocol.md, Limits).
        work_base_radius: nor into the vertical cylinder of this radius about the base
            axis [m] (warning 1).
        stretched_margin: the elbow may not straighten closer than this to
            |q3 - 90 deg| = 0 [rad] (warning 2).
    """

    l1: float = 0.105
    l2: float = 0.400
    l3: float = 0.320
    l4: float = 0.160
    lower: tuple[float, ...] = field(default_factory=_default_lower)
    upper: tuple[float, ...] = field(default_factory=_default_upper)
    max_speed: tuple[float, ...] = field(default_factory=_default_speed)
    max_accel: tuple[float, ...] = field(
        default_factory=lambda: tuple(200.0 * DEG for _ in range(N_JOINTS))
    )
    gripper_max: float = 0.090
    singular_tol: float = 1e-3
    work_floor_z: float = -0.350
    work_base_radius: float = 0.090
    stretched_margin: float = 3.0 * DEG

    def __post_init__(self) -> None:
        for name in ("l1", "l2", "l3", "l4"):
            value = getattr(self, name)
            if not (math.isfinite(value) and 0.0 <= value <= 2.0):
                raise ConfigError(f"`{name}` must be a length in [0, 2] m, got {value!r}")
        if self.l2 <= 0 or self.l3 <= 0:
            raise ConfigError("`l2` and `l3` must be positive lengths [m]")
        for name in ("lower", "upper", "max_speed", "max_accel"):
            value = getattr(self, name)
            if len(value) != N_JOINTS or not all(math.isfinite(v) for v in value):
                raise ConfigError(f"`{name}` must hold {N_JOINTS} finite numbers, got {value!r}")
        for j, (lo, hi) in enumerate(zip(self.lower, self.upper, strict=True), start=1):
            if not lo < hi:
                raise ConfigError(
                    f"joint {j}: lower limit {lo / DEG:.1f} deg must be below upper "
                    f"limit {hi / DEG:.1f} deg"
                )
        for j, v in enumerate(self.max_speed, start=1):
            if not 0.0 < v <= 50.0 * DEG + 1e-12:
                raise ConfigError(
                    f"joint {j}: `max_speed` {v / DEG:.2f} deg/s must be in (0, 50] deg/s, "
                    "the arm's fastest speed"
                )
        self._check_work_area()
        if not 0.0 < self.gripper_max <= 0.2:
            raise ConfigError(f"`gripper_max` must be in (0, 0.2] m, got {self.gripper_max!r}")

    def _check_work_area(self) -> None:
        if not (math.isfinite(self.work_floor_z) and -2.0 <= self.work_floor_z <= 2.0):
            raise ConfigError(f"`work_floor_z` must be in [-2, 2] m, got {self.work_floor_z!r}")
        if not (math.isfinite(self.work_base_radius) and 0.0 <= self.work_base_radius <= 1.0):
            raise ConfigError(
                f"`work_base_radius` must be in [0, 1] m, got {self.work_base_radius!r}"
            )
        if not (math.isfinite(self.stretched_margin) and 0.0 <= self.stretched_margin <= 45 * DEG):
            raise ConfigError(
                f"`stretched_margin` must be in [0, 45] deg, got {self.stretched_margin!r} rad"
            )

    @property
    def lower_array(self) -> np.ndarray:
        """Lower joint limits [rad], shape (6,)."""
        return np.asarray(self.lower, dtype=float)

    @property
    def upper_array(self) -> np.ndarray:
        """Upper joint limits [rad], shape (6,)."""
        return np.asarray(self.upper, dtype=float)

    @classmethod
    def from_mapping(cls, data: dict[str, Any], *, source: str = "<mapping>") -> ArmConfig:
        """Build a config from thesis units: lengths in mm, angles in deg.

        Keys: ``l1_mm`` .. ``l4_mm``, ``lower_deg``, ``upper_deg``, ``max_speed_deg_s``,
        ``max_accel_deg_s2``, ``gripper_max_mm``, ``work_floor_z_mm``,
        ``work_base_radius_mm``, ``stretched_margin_deg``. Unknown keys are an error.

        Raises:
            ConfigError: naming the source and the key.
        """
        scale = {
            "l1_mm": ("l1", 1e-3),
            "l2_mm": ("l2", 1e-3),
            "l3_mm": ("l3", 1e-3),
            "l4_mm": ("l4", 1e-3),
            "lower_deg": ("lower", DEG),
            "upper_deg": ("upper", DEG),
            "max_speed_deg_s": ("max_speed", DEG),
            "max_accel_deg_s2": ("max_accel", DEG),
            "gripper_max_mm": ("gripper_max", 1e-3),
            "work_floor_z_mm": ("work_floor_z", 1e-3),
            "work_base_radius_mm": ("work_base_radius", 1e-3),
            "stretched_margin_deg": ("stretched_margin", DEG),
        }
        kwargs: dict[str, Any] = {}
        for key, value in data.items():
            if key not in scale:
                raise ConfigError(
                    f"{source}: unknown arm setting `{key}` (allowed: {sorted(scale)})"
                )
            name, factor = scale[key]
            try:
                if isinstance(value, list | tuple):
                    kwargs[name] = tuple(float(v) * factor for v in value)
                else:
                    kwargs[name] = float(value) * factor
            except (TypeError, ValueError) as exc:
                raise ConfigError(f"{source}: `{key}` must be numeric, got {value!r}") from exc
        try:
            return cls(**kwargs)
        except ConfigError as exc:
            raise ConfigError(f"{source}: {exc}") from exc

    def with_overrides(self, **changes: Any) -> ArmConfig:
        """A copy with some SI fields replaced (validated again)."""
        known = {f.name for f in fields(self)}
        bad = sorted(set(changes) - known)
        if bad:
            raise ConfigError(f"unknown arm setting(s) {bad}")
        return replace(self, **changes)


def read_json_object(file: Path, what: str) -> dict[str, Any]:
    """The JSON object in ``file``; ``what`` names it in errors (e.g. "arm config").

    Raises:
        ConfigError: naming the file (and line): unreadable, not JSON, not an object.
    """
    try:
        data = json.loads(file.read_text())
    except OSError as exc:
        raise ConfigError(f"{file}: cannot read {what}: {exc.strerror}") from exc
    except json.JSONDecodeError as exc:
        raise ConfigError(f"{file}:{exc.lineno}: not valid JSON: {exc.msg}") from exc
    if not isinstance(data, dict):
        raise ConfigError(f"{file}: {what} must be a JSON object")
    return data


def load_arm_config(path: str | os.PathLike[str] | None = None) -> ArmConfig:
    """Defaults, then a JSON file (``path`` or ``$MANUS_ARM_CONFIG``) in thesis units."""
    chosen = path if path is not None else os.environ.get("MANUS_ARM_CONFIG")
    if not chosen:
        return ArmConfig()
    file = Path(chosen)
    return ArmConfig.from_mapping(read_json_object(file, "arm config"), source=str(file))


UNFOLDED_Q_DEG = (0.0, 30.0, -30.0, 0.0, -60.0, 0.0)
"""The operational (unfolded) pose (docs/protocol.md, Kinematics), DH joint angles [deg]."""

FOLDED_Q_DEG = (0.0, -90.0, -90.0, 0.0, -90.0, 0.0)
"""The compact folded pose (upper arm up, forearm down, gripper at about (160, 105, 80) mm)
used by the simulator's fold-in procedure and the named pose `folded` [deg]."""

FOLDED_WITHIN_DEG = 5.0
"""An arm whose every joint is this close to :data:`FOLDED_Q_DEG` stands folded [deg]."""


_FOLDED_RAD = tuple(math.radians(v) for v in FOLDED_Q_DEG)
_FOLDED_WITHIN_RAD = math.radians(FOLDED_WITHIN_DEG)


def is_folded(q: Sequence[float]) -> bool:
    """The DH joint angles ``q`` [rad], 6 values, are the folded pose (within
    :data:`FOLDED_WITHIN_DEG` per joint)."""
    return all(abs(a - b) <= _FOLDED_WITHIN_RAD for a, b in zip(q, _FOLDED_RAD, strict=True))


DEFAULT_ARM = ArmConfig()
"""The thesis arm with the default limits (shared, immutable)."""
