"""The simulated camera's settings: where it looks from, how often, how well.

A JSON object under the simulator configuration's ``camera`` key; the keys are the field
names below (units in the names). Defaults: a camera on a mast behind the user's right
shoulder, looking forward and down at the default scene's table, 10 frames a second,
80-100 ms from capture to publication, 3 mm and 1.5 deg of noise, 5 % of the objects
missed in a frame and 1 % of the frames lost.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

from manus.errors import ConfigError


def _within(name: str, value: Any, lo: float, hi: float) -> None:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(f"camera: `{name}` must be a number in [{lo:g}, {hi:g}], got {value!r}")
    if not (math.isfinite(value) and lo <= value <= hi):
        raise ConfigError(f"camera: `{name}` must be in [{lo:g}, {hi:g}], got {value!r}")


@dataclass(frozen=True)
class CameraConfig:
    """The simulated camera (docs/objects.md, The simulated camera).

    Attributes:
        enabled: publish on ``perception/objects``.
        source: its name in the messages.
        xyz_mm: its position in the chair frame [mm].
        rpy_deg: its orientation in the chair frame (roll, pitch, yaw) [deg]; it looks
            along its own x (pitch > 0 looks down).
        fov_deg: full field of view (horizontal, vertical) [deg].
        range_m: nearest and farthest distance it sees an object's centre at [m].
        period_ms: time between two captures [ms].
        latency_ms: from a capture to its publication [ms].
        latency_jitter_ms: plus a seeded uniform delay up to this; frames stay in order [ms].
        noise_mm: standard deviation of the reported position, per axis [mm].
        noise_deg: standard deviation of each reported angle (yaw, pitch, roll) [deg].
        dropout: probability that a visible object is missing from a frame [-].
        frame_dropout: probability that a whole frame is lost [-].
        min_visible: fraction of an object's sample rays (its centre and six points
            towards its faces) that must reach the camera for it to be seen [-].
        confidence: the confidence of a fully visible object; a partly hidden one gets
            this times its visible fraction [-].
    """

    enabled: bool = True
    source: str = "camera"
    xyz_mm: tuple[float, float, float] = (100.0, -250.0, 1450.0)
    rpy_deg: tuple[float, float, float] = (0.0, 37.0, 10.0)
    fov_deg: tuple[float, float] = (70.0, 55.0)
    range_m: tuple[float, float] = (0.2, 2.5)
    period_ms: float = 100.0
    latency_ms: float = 80.0
    latency_jitter_ms: float = 20.0
    noise_mm: float = 3.0
    noise_deg: float = 1.5
    dropout: float = 0.05
    frame_dropout: float = 0.01
    min_visible: float = 0.5
    confidence: float = 0.95

    def __post_init__(self) -> None:
        if not isinstance(self.enabled, bool):
            raise ConfigError(f"camera: `enabled` must be true or false, got {self.enabled!r}")
        if not self.source or not self.source.replace("_", "").replace("-", "").isalnum():
            raise ConfigError(f"camera: `source` must be a name, got {self.source!r}")
        for name, count in (("xyz_mm", 3), ("rpy_deg", 3), ("fov_deg", 2), ("range_m", 2)):
            value = tuple(getattr(self, name))
            if len(value) != count:
                raise ConfigError(f"camera: `{name}` needs {count} numbers, got {value!r}")
            object.__setattr__(self, name, tuple(float(v) for v in value))
        for v in self.xyz_mm:
            _within("xyz_mm", v, -10_000.0, 10_000.0)
        for v in self.rpy_deg:
            _within("rpy_deg", v, -360.0, 360.0)
        for v in self.fov_deg:
            _within("fov_deg", v, 1.0, 179.0)
        near, far = self.range_m
        _within("range_m", near, 0.0, 100.0)
        _within("range_m", far, near, 100.0)
        _within("period_ms", self.period_ms, 10.0, 10_000.0)
        _within("latency_ms", self.latency_ms, 0.0, 10_000.0)
        _within("latency_jitter_ms", self.latency_jitter_ms, 0.0, 10_000.0)
        _within("noise_mm", self.noise_mm, 0.0, 1000.0)
        _within("noise_deg", self.noise_deg, 0.0, 180.0)
        for name in ("dropout", "frame_dropout", "min_visible", "confidence"):
            _within(name, getattr(self, name), 0.0, 1.0)

    @classmethod
    def from_mapping(cls, data: dict[str, Any], *, source: str = "<mapping>") -> CameraConfig:
        """Build from JSON-like data.

        Raises:
            ConfigError: an unknown key or a bad value, naming ``source``.
        """
        known = {f.name for f in fields(cls)}
        for key in data:
            if key not in known:
                raise ConfigError(f"{source}: unknown camera setting `{key}` ({sorted(known)})")
        try:
            return cls(**data)
        except (TypeError, ValueError) as exc:
            raise ConfigError(f"{source}: {exc}") from exc
