"""When closing jaws hold an object, and when a grasp slips.

In the gripper frame (the stack's "gripper pose": z the approach axis, x the jaw axis,
the origin between the fingertips' pads) the jaws are the box between the fingers:
``|x| <= opening / 2``, ``|y| <= JAW_HALF_WIDTH``, ``-JAW_DEPTH <= z <= JAW_REACH``. An
object whose centre lies in it is *between the jaws*. Closing jaws reach it when the
opening comes down to its width along the jaw axis
(:func:`~services.simulator.objects.width_along`); the fingers then centre it along x
(one finger pushes it until the other touches) and:

A finger that reaches a standing object before the other (the object lies off the grasp
point along the jaw axis) pushes it along the surface it stands on (:func:`pushed`), so
that it only touches it: the truth counts no contact of a finger with the object it
closes on, and at the grasp the object is where the fingers centred it.

- the grasp **holds** when the object's centre is within ``tolerance`` of the grasp point
  (the gripper frame's origin) across the jaw axis (in y and in z): from then on the
  object moves with the gripper and the jaws stay at its width;
- otherwise it **slips**: the fingers close past it and it is left where it is (or falls
  to the surface below, if it was lifted).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from manus.urdf import GRIPPER_DEPTH
from services.simulator.objects import SimObject, width_along

JAW_HALF_WIDTH = 0.025
"""Half the fingers' width, across the jaw axis (the gripper box's y) [m]."""
JAW_REACH = 0.01
"""How far the fingertips reach past the gripper frame's origin along z [m]."""
JAW_DEPTH = GRIPPER_DEPTH - JAW_REACH
"""How deep the jaws go behind the origin along z, to the palm [m]."""


class Contact(NamedTuple):
    """What closing jaws found on an object.

    Attributes:
        width: the object's extent along the jaw axis: where the jaws stop [m].
        offset: its centre's distance from the grasp point across the jaw axis, the larger
            of |y| and |z| in the gripper frame [m].
        grip: its placement in the gripper frame once the fingers centred it, (4, 4).
    """

    width: float
    offset: float
    grip: np.ndarray


def between_jaws(
    obj: SimObject, pose: np.ndarray, gripper: np.ndarray, opening: float
) -> Contact | None:
    """The contact of ``obj`` at ``pose`` with jaws ``opening`` [m] apart at ``gripper``
    (chair frame, (4, 4) each), or None when its centre is not between the jaws or it is
    wider than the opening."""
    local = np.linalg.solve(gripper, pose)
    x, y, z = (float(v) for v in local[:3, 3])
    if abs(y) > JAW_HALF_WIDTH or not -JAW_DEPTH <= z <= JAW_REACH or abs(x) > opening / 2.0:
        return None
    width = width_along(obj.shape, obj.size, local[:3, :3].T @ np.array([1.0, 0.0, 0.0]))
    if width > opening + 1e-9:
        return None
    grip = local.copy()
    grip[0, 3] = 0.0  # the fingers centre it along the jaw axis
    return Contact(width, max(abs(y), abs(z)), grip)


def holds(contact: Contact, tolerance: float) -> bool:
    """Whether a grasp at ``contact`` holds (its offset within ``tolerance`` [m])."""
    return contact.offset <= tolerance + 1e-12


PUSH_FLAT = 0.5
"""A finger pushes a standing object along its surface only when the jaw axis is at most
60 degrees from horizontal: the horizontal part of its unit vector at least this [-]."""


def pushed(
    pose: np.ndarray, gripper: np.ndarray, opening: float, width: float
) -> np.ndarray | None:
    """Where a standing object at ``pose``, ``width`` [m] wide along the jaw axis, is once
    the jaws at ``gripper`` close to ``opening`` [m] (chair frame, (4, 4) each): pushed
    along the surface until the finger that reached it only touches it (its centre at most
    ``(opening - width) / 2`` off the grasp point along the jaw axis). None: no finger
    reached it, or the jaw axis is too steep to push it along its surface
    (:data:`PUSH_FLAT`)."""
    x = float(np.linalg.solve(gripper, pose)[0, 3])
    excess = abs(x) - max(0.0, (opening - width) / 2.0)
    if excess <= 0.0:
        return None
    flat = np.array([gripper[0, 0], gripper[1, 0], 0.0])  # the jaw axis, horizontal part
    n = float(np.linalg.norm(flat))
    if n < PUSH_FLAT:
        return None
    out = pose.copy()
    out[:3, 3] -= math.copysign(excess / n, x) * flat / n  # moves it by -excess along x
    return out
