"""Slow-down of a jog near the wrist and elbow singularities and the joint limits.

Each zone has a distance measure in degrees: the wrist's |q5| from 0 or 180 deg (q4 and
q6 aligned), the elbow's |q3 - 90 deg| (fully stretched, which the arm itself refuses
within 3 deg) and each joint's distance to its nearer limit. A step that brings a
measure below its ``slow`` distance is shortened in proportion to the distance left
(``(m - stop) / (slow - stop)``, from where it starts), and never past ``stop``; within
:data:`STOP_BAND_DEG` of it the step is not taken: the arm comes to rest before the
singularity or the limit, and a step away from it is never
slowed, so the user can always back out. The whole step is scaled by one factor, so a
Cartesian jog keeps its direction while it slows.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

from manus.config import ArmConfig
from schemas.jog import LimitKind
from services.controller.jog_config import JogConfig


class Slowdown(NamedTuple):
    """How much of a step to take, and what holds it back (a ``JogLimit`` of the state).

    Attributes:
        scale: share of the step to take [-], in [0, 1].
        kind: what holds it back (:class:`~schemas.jog.LimitKind`; '' when nothing does).
        object: which zone, speed or object (``wrist``, ``joint 3``, ``motors``, ``head``).
        angle: a zone's measure where the step starts [rad] (0 otherwise).
        words: what holds it back, in words that do not change while it does.
        body: the collision guard: the arm body nearest to ``object`` ('' otherwise).
        distance: the collision guard: that body's distance to it [m] (0 otherwise).
    """

    scale: float
    kind: str = ""
    object: str = ""
    angle: float = 0.0
    words: str = ""
    body: str = ""
    distance: float = 0.0


FREE = Slowdown(1.0)
STOP_BAND_DEG = 0.5
"""Within this of a zone's stop the step is not taken at all [deg]: the approach, slower
and slower, ends in finite time."""

_JOINTS = tuple(f"joint {j}" for j in range(1, 7))
_NAMES = {
    "wrist": "the wrist singularity (q5 near 0 or 180 deg)",
    "elbow": "the elbow stretched (q3 near 90 deg)",
}


def measures(q: Sequence[float], arm: ArmConfig) -> list[tuple[LimitKind, str, float]]:
    """Each zone's kind, object and distance [deg] at DH angles ``q`` [rad], shape (6,)."""
    out = [
        (LimitKind.SINGULARITY, "wrist", math.degrees(abs(math.remainder(q[4], math.pi)))),
        (
            LimitKind.SINGULARITY,
            "elbow",
            math.degrees(abs(math.remainder(q[2] - math.pi / 2, 2 * math.pi))),
        ),
    ]
    for j, name in enumerate(_JOINTS):
        room = min(q[j] - arm.lower[j], arm.upper[j] - q[j])
        out.append((LimitKind.JOINT_LIMIT, name, math.degrees(room)))
    return out


def slowdown(
    q_from: Sequence[float], q_to: Sequence[float], arm: ArmConfig, cfg: JogConfig
) -> Slowdown:
    """The share of the step ``q_from`` -> ``q_to`` [rad] to take (module docstring)."""
    zones = {
        "wrist": (cfg.wrist_slow_deg, cfg.wrist_stop_deg),
        "elbow": (cfg.elbow_slow_deg, cfg.elbow_stop_deg),
    }
    best = FREE
    for (kind, name, m0), (_, _, m1) in zip(
        measures(q_from, arm), measures(q_to, arm), strict=True
    ):
        slow, stop = zones.get(name, (cfg.limit_slow_deg, cfg.limit_stop_deg))
        if m1 >= m0 or m1 >= slow:
            continue  # moving away, or still clear
        share = min(1.0, max(0.0, (m0 - stop) / (slow - stop)))
        share = min(share, max(0.0, (m0 - stop) / (m0 - m1)))  # never past the stop
        if m0 - stop <= STOP_BAND_DEG:
            share = 0.0
        if share < best.scale:
            zone = _NAMES.get(name, f"the limit of {name}")
            words = f"{zone}: slows within {slow:g} deg, stops at {stop:g} deg"
            best = Slowdown(share, kind, name, math.radians(m0), words)
    return best
