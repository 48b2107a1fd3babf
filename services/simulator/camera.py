"""The simulated camera: a perception node's output, made from the simulator's truth.

Every ``period_ms`` it captures (at the simulator's time, between ticks as anywhere) and,
``latency_ms`` plus a seeded jitter later, publishes a :class:`~schemas.objects.Perception`
stamped with the capture time, as a real camera and pose estimator do. An object is seen
when its centre is in the field of view and range and at least ``min_visible`` of its
seven sample rays (to its centre and to six points towards its faces) reach the camera
past every occluder: the arm's bodies (fingers included), the scene's objects (the
person first of all) and the other objects. A seen object is reported with seeded
Gaussian noise on its position and angles, unless a seeded dropout misses it; a whole
frame can be lost too (its ``seq`` is skipped). Objects that left the simulator are
reported ``removed`` in the next frame.

Lines of sight are checked exactly against the primitives (:mod:`.rays`), all of a frame
in one vectorised pass. Deterministic: one generator (seeded from the simulator's seed)
and the same number of draws per frame and per object whatever is seen.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from manus.orientation import matrix_to_ypr
from manus.scene import Scene, pose_matrix
from schemas.objects import ObjectShape, ObservedObject, Perception
from services.simulator.camera_config import CameraConfig
from services.simulator.objects import SimObject
from services.simulator.rays import Occluders, Primitive

MS = 1_000_000
"""One millisecond [ns]."""
SAMPLE_FRACTION = 0.8
"""The six side samples lie this far from the centre towards each face [-]."""


def scene_occluders(scene: Scene | None) -> list[Primitive]:
    """The scene's objects as occluders (planes left out: the camera is above the floor)."""
    return [
        Primitive(o.body.shape, o.body.size, o.body.pose)
        for o in (scene.objects if scene is not None else ())
        if o.body.shape != "plane"
    ]


def sample_points(obj: SimObject, pose: np.ndarray) -> np.ndarray:
    """The object's centre and six points towards its faces, chair frame, (7, 3) [m]."""
    s = obj.size
    if obj.shape == ObjectShape.BOX:
        half = np.array(s) / 2.0
    elif obj.shape == ObjectShape.SPHERE:
        half = np.full(3, s[0])
    else:
        half = np.array([s[0], s[0], obj.half_height])
    local = np.vstack([np.zeros(3), np.diag(half), -np.diag(half)]) * SAMPLE_FRACTION
    return np.asarray(local @ pose[:3, :3].T + pose[:3, 3])


class Camera:
    """The simulated camera's schedule and frames (see the module docstring).

    Args:
        config: its settings.
        rng: its own seeded generator.
        scene: the scene whose objects occlude (None: none).
    """

    def __init__(self, config: CameraConfig, rng: np.random.Generator, scene: Scene | None) -> None:
        self.config = config
        self.rng = rng
        self.pose = pose_matrix(
            [v * 1e-3 for v in config.xyz_mm], [math.radians(v) for v in config.rpy_deg]
        )
        self._inverse = np.linalg.inv(self.pose)
        self._fixed = Occluders(scene_occluders(scene))
        self._period = round(config.period_ms * MS)
        self.next_capture_ns = self._period
        """When the next frame is captured [ns]."""
        self._pending: deque[tuple[int, Perception]] = deque()
        self._last_out = 0
        self._seq = 0
        self._reported: set[str] = set()

    @property
    def fixed_occluders(self) -> int:
        """How many of the scene's objects may block its view."""
        return self._fixed.count

    def next_event_ns(self) -> int:
        """When the camera next captures or publishes [ns]."""
        if self._pending:
            return min(self.next_capture_ns, self._pending[0][0])
        return self.next_capture_ns

    def capture(
        self,
        t_ns: int,
        objects: list[tuple[SimObject, np.ndarray]],
        occluders: list[Primitive],
    ) -> None:
        """Capture the frame due at ``t_ns``: ``objects`` at their poses and the moving
        ``occluders`` (the arm's bodies) as they are now (chair frame)."""
        cfg, rng = self.config, self.rng
        self.next_capture_ns = t_ns + self._period
        seq, self._seq = self._seq, self._seq + 1
        lost = rng.random() < cfg.frame_dropout
        delay = cfg.latency_ms + rng.uniform(0.0, cfg.latency_jitter_ms)
        scale = np.repeat([cfg.noise_mm * 1e-3, math.radians(cfg.noise_deg)], 3)
        draws = [(rng.random() < cfg.dropout, rng.normal(0.0, 1.0, 6) * scale) for _ in objects]
        removed = sorted(self._reported - {obj.id for obj, _ in objects})
        if lost:
            return
        visible = self._visible(objects, occluders)
        seen: list[ObservedObject] = []
        for (obj, pose), (missed, noise), fraction in zip(objects, draws, visible, strict=True):
            if missed or fraction < cfg.min_visible:
                continue
            ypr = np.array(matrix_to_ypr(pose[:3, :3])) + noise[3:]
            seen.append(
                ObservedObject(
                    id=obj.id,
                    cls=obj.cls,
                    shape=obj.shape,
                    size=list(obj.size),
                    xyz=[float(v) for v in pose[:3, 3] + noise[:3]],
                    ypr=[float(math.remainder(v, math.tau)) for v in ypr],
                    confidence=cfg.confidence * fraction,
                )
            )
        self._reported = (self._reported - set(removed)) | {o.id for o in seen}
        out_ns = max(t_ns + round(delay * MS), self._last_out)
        self._last_out = out_ns
        msg = Perception(stamp_ns=t_ns, seq=seq, source=cfg.source, objects=seen, removed=removed)
        self._pending.append((out_ns, msg))

    def due(self, t_ns: int) -> list[tuple[int, Perception]]:
        """The frames whose publication time has come by ``t_ns``, with that time [ns]."""
        out = []
        while self._pending and self._pending[0][0] <= t_ns:
            out.append(self._pending.popleft())
        return out

    # -- what it sees -----------------------------------------------------------------------------

    def in_view(self, xyz: np.ndarray) -> bool:
        """Whether the point ``xyz`` (chair frame) [m] is in the field of view and range."""
        p = self._inverse[:3, :3] @ xyz + self._inverse[:3, 3]
        near, far = self.config.range_m
        if p[0] <= 0.0 or not near <= float(np.linalg.norm(p)) <= far:
            return False
        h, v = (math.radians(a) / 2.0 for a in self.config.fov_deg)
        return abs(math.atan2(p[1], p[0])) <= h and abs(math.atan2(p[2], p[0])) <= v

    def _visible(
        self, objects: list[tuple[SimObject, np.ndarray]], occluders: list[Primitive]
    ) -> list[float]:
        """Per object, the fraction of its sample rays that reach the camera (0: out of
        view), every ray against every occluder at once (an object never hides itself)."""
        looked = [k for k, (_, pose) in enumerate(objects) if self.in_view(pose[:3, 3])]
        out = [0.0] * len(objects)
        if not looked:
            return out
        points = np.vstack([sample_points(*objects[k]) for k in looked])
        eye = self.pose[:3, 3]
        moving = [*occluders, *(Primitive(obj.shape, obj.size, pose) for obj, pose in objects)]
        hit = np.vstack([self._fixed.blocked(eye, points), Occluders(moving).blocked(eye, points)])
        first = len(hit) - len(objects)
        n = len(points) // len(looked)
        for i, k in enumerate(looked):
            rows = slice(i * n, (i + 1) * n)
            hit[first + k, rows] = False
            out[k] = float(1.0 - hit[:, rows].any(axis=0).mean())
        return out
