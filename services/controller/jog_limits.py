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
from services.controller.jog_config import JogConfig


class Slowdown(NamedTuple):
    """How much of a step to take, and why.

    Attributes:
        scale: share of the step to take [-], in [0, 1].
        reason: the zone that set it, in words ('' when the step is not slowed).
    """

    scale: float
    reason: str


FREE = Slowdown(1.0, "")
STOP_BAND_DEG = 0.5
"""Within this of a zone's stop the step is not taken at all [deg]: the approach, slower
and slower, ends in finite time."""


def measures(q: Sequence[float], arm: ArmConfig) -> list[tuple[str, float]]:
    """Each zone's name and distance [deg] at DH angles ``q`` [rad], shape (6,)."""
    out = [
        ("wrist singularity (q5 near 0/180 deg)", math.degrees(abs(math.remainder(q[4], math.pi)))),
        (
            "elbow stretched (q3 near 90 deg)",
            math.degrees(abs(math.remainder(q[2] - math.pi / 2, 2 * math.pi))),
        ),
    ]
    for j in range(6):
        room = min(q[j] - arm.lower[j], arm.upper[j] - q[j])
        out.append((f"joint {j + 1} limit", math.degrees(room)))
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
    for (name, m0), (_, m1) in zip(measures(q_from, arm), measures(q_to, arm), strict=True):
        slow, stop = zones.get(name.split()[0], (cfg.limit_slow_deg, cfg.limit_stop_deg))
        if m1 >= m0 or m1 >= slow:
            continue  # moving away, or still clear
        share = min(1.0, max(0.0, (m0 - stop) / (slow - stop)))
        share = min(share, max(0.0, (m0 - stop) / (m0 - m1)))  # never past the stop
        if m0 - stop <= STOP_BAND_DEG:
            share = 0.0
        if share < best.scale:
            verb = "stopped" if share <= 0.0 else f"slowed to {share * 100:.0f} %"
            best = Slowdown(
                share,
                f"{verb}: {name}, {m0:.1f} deg from it (slowing within {slow:g}, "
                f"stopping at {stop:g} deg)",
            )
    return best
