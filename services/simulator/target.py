"""The simulator's moving target: its true motion and its tracker's frames.

:class:`MovingTarget` is a pure function of simulated time for the truth (where the
target and the body it moves with are, whether the tracker sees it) and a small
schedule for the tracker: a capture every ``1 / rate_hz``, published ``latency_ms``
(plus seeded jitter, frames kept in order) later with seeded noise, unless the frame is
dropped or the target is lost (``lost_reports``: nothing, or a frame saying so). The
random numbers of a capture are drawn whatever happens to it, so a setting changes only
what it names. Settings: :mod:`services.simulator.target_config`.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from manus.errors import ConfigError
from manus.orientation import matrix_to_ypr, ypr_to_matrix
from manus.scene import Scene
from schemas.target import TargetFrame, TargetPose, TargetTruth
from services.simulator.target_config import TargetConfig

MS = 1_000_000
"""One millisecond [ns]."""


class MovingTarget:
    """The target, its body and its tracker (see the module docstring).

    Args:
        config: the target's settings.
        rng: its own seeded generator.
        scene: the simulator's scene (where its ``body`` is found; None: no scene).

    Raises:
        ConfigError: ``body`` names no person of the scene.
    """

    def __init__(self, config: TargetConfig, rng: np.random.Generator, scene: Scene | None) -> None:
        self.config = config
        self._rng = rng
        self.rest = np.asarray(config.xyz_mm, dtype=float) / 1000.0
        """Where the target rests, chair frame [m], shape (3,)."""
        yaw, pitch, roll = (math.radians(v) for v in config.ypr_deg)
        self.rotation = ypr_to_matrix(yaw, pitch, roll)
        self._ypr = [float(v) for v in np.radians(config.ypr_deg)]
        self.body_rest: np.ndarray | None = None
        """The body's pose at rest (4x4, chair frame; None: no body)."""
        if config.body:
            found = [o for o in scene.objects if o.name == config.body] if scene else []
            if not found or found[0].cls != "person":
                persons = [o.name for o in scene.objects if o.cls == "person"] if scene else []
                raise ConfigError(
                    f"target: `body` {config.body!r} is not a person of the scene "
                    f"(persons: {persons})"
                )
            self.body_rest = found[0].body.pose.copy()
        self._amp = np.asarray(config.sway_mm, dtype=float) / 1000.0
        self._phase = np.radians(config.sway_phase_deg)
        self._next_capture = round(config.start_s * 1e9)
        self._pending: deque[tuple[int, TargetPose]] = deque()
        self._last_out = 0
        self._seq = 0

    # -- the truth ---------------------------------------------------------------------------

    def offset(self, t_ns: int) -> np.ndarray:
        """Displacement from rest at ``t_ns`` [m], shape (3,): the sway and the moves."""
        t = t_ns / 1e9
        cfg = self.config
        out = self._amp * np.sin(2.0 * math.pi * cfg.sway_hz * t + self._phase)
        for move in cfg.moves:
            share = move.share(t)
            if share > 0.0:
                out = out + share * np.asarray(move.by_mm) / 1000.0
        return np.asarray(out)

    def position(self, t_ns: int) -> np.ndarray:
        """The target point at ``t_ns``, chair frame [m], shape (3,)."""
        return np.asarray(self.rest + self.offset(t_ns))

    def body_pose(self, t_ns: int) -> np.ndarray | None:
        """The body's pose at ``t_ns`` (4x4, chair frame; it moves with the target)."""
        if self.body_rest is None:
            return None
        pose = self.body_rest.copy()
        pose[:3, 3] += self.offset(t_ns)
        return pose

    def visible(self, t_ns: int) -> bool:
        """The tracker sees the target at ``t_ns``."""
        t = t_ns / 1e9
        return not any(w.holds(t) for w in self.config.lost)

    def truth(self, t_ns: int) -> TargetTruth:
        """The true target and body at ``t_ns``."""
        body = self.body_pose(t_ns)
        return TargetTruth(
            source=self.config.source,
            xyz=[float(v) for v in self.position(t_ns)],
            ypr=list(self._ypr),
            body=self.config.body,
            body_xyz=[] if body is None else [float(v) for v in body[:3, 3]],
            body_ypr=[] if body is None else [float(v) for v in matrix_to_ypr(body[:3, :3])],
            visible=self.visible(t_ns),
        )

    # -- the tracker -------------------------------------------------------------------------

    def next_event_ns(self) -> int:
        """The next capture or publication [ns]."""
        if self._pending:
            return min(self._next_capture, self._pending[0][0])
        return self._next_capture

    def due(self, t_ns: int) -> list[tuple[int, TargetPose]]:
        """Captures up to ``t_ns`` scheduled, and the frames published by then:
        (publication time [ns], frame), in order."""
        cfg = self.config
        while self._next_capture <= t_ns:
            self._capture(self._next_capture)
            self._next_capture += cfg.period_ns
        out = []
        while self._pending and self._pending[0][0] <= t_ns:
            out.append(self._pending.popleft())
        return out

    def _capture(self, t_ns: int) -> None:
        cfg = self.config
        noise = self._rng.normal(0.0, cfg.noise_mm / 1000.0, 3)
        jitter = self._rng.uniform(0.0, cfg.jitter_ms * MS)
        dropped = self._rng.uniform() < cfg.drop
        seen = self.visible(t_ns)
        if dropped or (not seen and cfg.lost_reports == "silent"):
            return
        at = max(t_ns + round(cfg.latency_ms * MS + jitter), self._last_out)
        self._last_out = at
        self._pending.append((at, self._frame(t_ns, noise, seen)))

    def _frame(self, t_ns: int, noise: np.ndarray, seen: bool) -> TargetPose:
        body = self.body_pose(t_ns)
        xyz = self.position(t_ns) + noise
        pose = TargetPose(
            stamp_ns=t_ns,
            seq=self._seq,
            source=self.config.source,
            frame=TargetFrame.CHAIR,
            tracked=seen,
            xyz=[float(v) for v in xyz],
            ypr=list(self._ypr),
            confidence=1.0 if seen else 0.0,
            body=self.config.body,
            body_xyz=[] if body is None else [float(v) for v in body[:3, 3] + noise],
            body_ypr=[] if body is None else [float(v) for v in matrix_to_ypr(body[:3, :3])],
        )
        self._seq += 1
        return pose
