"""Where the arm may go: the fully stretched elbow and the forbidden work area.

Pure functions in DH joint angles [deg] and gripper positions [mm]. Each "violation" is a
non-negative depth into a forbidden region (0 = allowed); the arm refuses a motion that
would make a violation deeper, so an arm started in a forbidden place can still leave it.
"""

from __future__ import annotations

import math

import numpy as np

STRAIGHT_Q3_DEG = 90.0
"""DH q3 at which upper arm and forearm are aligned (the elbow fully stretched) [deg]."""


def stretch_violation(q_deg: np.ndarray, margin_deg: float) -> float:
    """How far [deg] the elbow is inside ``margin_deg`` of fully stretched (0 = clear).

    Args:
        q_deg: DH joint angles, shape (6,) [deg].
        margin_deg: closest allowed approach of |q3 - 90 deg| to 0 [deg].
    """
    bend = abs(math.remainder(float(q_deg[2]) - STRAIGHT_Q3_DEG, 360.0))
    return max(0.0, margin_deg - bend)


def area_violation(xyz_mm: np.ndarray, floor_z_mm: float, base_radius_mm: float) -> float:
    """Depth [mm] of the gripper into the forbidden work area (0 = allowed).

    Forbidden: below the floor plane z = ``floor_z_mm``, or inside the vertical cylinder of
    radius ``base_radius_mm`` around the base axis (the wheelchair and the arm's own base).

    Args:
        xyz_mm: gripper position in the base frame, shape (3,) [mm].
        floor_z_mm: lowest allowed z [mm].
        base_radius_mm: radius of the forbidden cylinder [mm].
    """
    below = floor_z_mm - float(xyz_mm[2])
    inside = base_radius_mm - math.hypot(float(xyz_mm[0]), float(xyz_mm[1]))
    return max(0.0, below, inside)
