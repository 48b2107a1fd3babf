"""The simulator's moving target: how it moves and how its tracker reports it (settings).

A target is a point in the chair frame (by default the user's mouth, in front of the
default scene's head) that sways, moves by steps (a sudden lean forward, a benchmark's
step), and is lost for a while; the body it moves with (the person's ``head``) moves
with it, rigidly. Its tracker publishes one :class:`schemas.target.TargetPose` per frame
(``rate_hz``), ``latency_ms`` after the capture, with seeded noise, jitter and dropped
frames. File keys (the simulator config's ``target`` object) are the field names below;
``moves`` and ``lost`` take lists of objects with the fields of :class:`TargetMove` and
:class:`LostWindow`. Times are simulator time since power-up [s].
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, fields
from typing import Any

from manus.errors import ConfigError

LOST_REPORTS = ("silent", "untracked")
"""What the tracker publishes while the target is lost: nothing, or frames that say so."""

MOUTH_XYZ_MM = (83.0, 0.0, 1192.0)
"""The mouth of the default scene's user: on the front of the head (a sphere of 110 mm
about (-20, 0, 1230) mm), 20 degrees below its centre [mm], chair frame."""


def _finite(name: str, value: Any, lo: float, hi: float) -> None:
    if not (isinstance(value, int | float) and math.isfinite(value) and lo <= value <= hi):
        raise ConfigError(f"target: `{name}` must be in [{lo:g}, {hi:g}], got {value!r}")


def _three(name: str, values: Any, limit: float) -> tuple[float, float, float]:
    if not isinstance(values, list | tuple) or len(values) != 3:
        raise ConfigError(f"target: `{name}` must hold 3 numbers, got {values!r}")
    for v in values:
        _finite(name, v, -limit, limit)
    a, b, c = (float(v) for v in values)
    return a, b, c


@dataclass(frozen=True)
class TargetMove:
    """A displacement of the target (and its body), smooth or sudden.

    Attributes:
        at_s: when it starts [s].
        by_mm: how far, chair frame (x, y, z) [mm].
        over_s: how long it takes, on a minimum-jerk profile (0: a jump) [s].
    """

    at_s: float
    by_mm: tuple[float, float, float]
    over_s: float = 0.0

    def __post_init__(self) -> None:
        _finite("moves.at_s", self.at_s, 0.0, 1e6)
        object.__setattr__(self, "by_mm", _three("moves.by_mm", self.by_mm, 1000.0))
        _finite("moves.over_s", self.over_s, 0.0, 60.0)

    def share(self, t_s: float) -> float:
        """How much of the move is done at ``t_s`` (0..1)."""
        if t_s <= self.at_s:
            return 0.0
        if self.over_s <= 0.0 or t_s >= self.at_s + self.over_s:
            return 1.0
        s = (t_s - self.at_s) / self.over_s
        return s * s * s * (10.0 - 15.0 * s + 6.0 * s * s)


@dataclass(frozen=True)
class LostWindow:
    """A time in which the tracker does not see the target.

    Attributes:
        at_s: when it starts [s].
        for_s: how long [s].
    """

    at_s: float
    for_s: float

    def __post_init__(self) -> None:
        _finite("lost.at_s", self.at_s, 0.0, 1e6)
        _finite("lost.for_s", self.for_s, 0.0, 1e6)

    def holds(self, t_s: float) -> bool:
        """The target is lost at ``t_s``."""
        return self.at_s <= t_s < self.at_s + self.for_s


@dataclass(frozen=True)
class TargetConfig:
    """The simulated moving target and its tracker (see the module docstring).

    Attributes:
        enabled: simulate it (off by default: the simulator then publishes no target).
        source: the tracker's name (``TargetPose.source``).
        xyz_mm: where the target rests, chair frame [mm] (default: the default user's mouth).
        ypr_deg: (yaw, pitch, roll) of its frame, chair frame [deg] (a mouth's x axis
            points out of the face: forward).
        body: the scene object (class person) that moves with it ('' : none, a free target).
        sway_mm: sway amplitude per chair axis (x, y, z) [mm].
        sway_hz: sway frequency [Hz].
        sway_phase_deg: sway phase per axis [deg].
        moves: displacements (a lean forward, a step).
        lost: windows in which the tracker does not see the target.
        lost_reports: ``silent`` (no frames while lost) or ``untracked`` (frames with
            ``tracked`` false).
        start_s: the tracker's first capture [s].
        rate_hz: the tracker's frame rate [Hz].
        latency_ms: from a capture to its publication [ms].
        jitter_ms: a uniform extra latency of 0..this, seeded [ms] (frames stay in order).
        noise_mm: standard deviation of the reported position per axis, seeded [mm].
        drop: probability that a frame is not published, seeded [-].
    """

    enabled: bool = False
    source: str = "mouth"
    xyz_mm: tuple[float, float, float] = MOUTH_XYZ_MM
    ypr_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    body: str = "head"
    sway_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    sway_hz: float = 0.2
    sway_phase_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    moves: tuple[TargetMove, ...] = ()
    lost: tuple[LostWindow, ...] = ()
    lost_reports: str = "silent"
    start_s: float = 0.0
    rate_hz: float = 30.0
    latency_ms: float = 40.0
    jitter_ms: float = 0.0
    noise_mm: float = 0.0
    drop: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.source, str) or not self.source:
            raise ConfigError(f"target: `source` must be a non-empty name, got {self.source!r}")
        object.__setattr__(self, "xyz_mm", _three("xyz_mm", self.xyz_mm, 5000.0))
        object.__setattr__(self, "ypr_deg", _three("ypr_deg", self.ypr_deg, 360.0))
        object.__setattr__(self, "sway_mm", _three("sway_mm", self.sway_mm, 500.0))
        object.__setattr__(
            self, "sway_phase_deg", _three("sway_phase_deg", self.sway_phase_deg, 360.0)
        )
        _finite("sway_hz", self.sway_hz, 0.0, 10.0)
        if self.lost_reports not in LOST_REPORTS:
            raise ConfigError(
                f"target: `lost_reports` {self.lost_reports!r} must be one of {LOST_REPORTS}"
            )
        _finite("start_s", self.start_s, 0.0, 1e6)
        _finite("rate_hz", self.rate_hz, 1.0, 100.0)
        _finite("latency_ms", self.latency_ms, 0.0, 1000.0)
        _finite("jitter_ms", self.jitter_ms, 0.0, 1000.0)
        _finite("noise_mm", self.noise_mm, 0.0, 100.0)
        _finite("drop", self.drop, 0.0, 1.0)
        object.__setattr__(self, "moves", tuple(self.moves))
        object.__setattr__(self, "lost", tuple(self.lost))

    @property
    def period_ns(self) -> int:
        """Time between two captures [ns]."""
        return round(1e9 / self.rate_hz)

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], *, source: str = "<mapping>") -> TargetConfig:
        """From JSON-like data (the simulator config's ``target`` object).

        Raises:
            ConfigError: naming the source and the key.
        """
        known = {f.name for f in fields(cls)}
        kwargs: dict[str, Any] = {}
        for key, value in data.items():
            if key not in known:
                raise ConfigError(f"{source}: unknown target setting `{key}` ({sorted(known)})")
            if key in ("moves", "lost"):
                kind: type[Any] = TargetMove if key == "moves" else LostWindow
                if not isinstance(value, list) or not all(isinstance(e, dict) for e in value):
                    raise ConfigError(f"{source}: `target.{key}` must be a list of objects")
                try:
                    kwargs[key] = tuple(kind(**entry) for entry in value)
                except TypeError as exc:
                    raise ConfigError(f"{source}: `target.{key}`: {exc}") from exc
            else:
                kwargs[key] = tuple(value) if isinstance(value, list) else value
        try:
            return cls(**kwargs)
        except ConfigError as exc:
            raise ConfigError(f"{source}: {exc}") from exc


NO_TARGET = TargetConfig()
"""No moving target (the default of :class:`services.simulator.config.SimConfig`)."""

__all__ = ["LOST_REPORTS", "MOUTH_XYZ_MM", "NO_TARGET", "LostWindow", "TargetConfig", "TargetMove"]
