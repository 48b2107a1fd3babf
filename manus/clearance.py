"""What the collision model reports: a check, the tightest clearance of a configuration
or a motion, and what the controller's guard needs of one configuration.

A configuration's *margin* per check is distance minus the clearance its class requires;
negative means violated (:mod:`manus.collision` computes them).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from schemas.collision import ClearanceReport


class Check(NamedTuple):
    """One distance the model watches.

    Attributes:
        body: the arm body.
        other: the object, zone or arm body it is kept from.
        cls: ``person``, ``chair``, ``environment``, ``self`` or ``zone``.
        required: the clearance [m].
    """

    body: str
    other: str
    cls: str
    required: float


class Clearance(NamedTuple):
    """The tightest check of one configuration (or of a motion).

    Attributes:
        margin: distance minus required clearance [m] (< 0: violated).
        distance: distance between the two [m] (a keep-in zone: to its boundary).
        check: which check.
        time: time along the motion [s] (0 for a single configuration).
        q: the configuration [rad], shape (6,).
    """

    margin: float
    distance: float
    check: Check
    time: float
    q: np.ndarray

    def report(self) -> ClearanceReport:
        """The message form."""
        c = self.check
        return ClearanceReport(
            distance=float(self.distance),
            required=float(c.required),
            body=c.body,
            other=c.other,
            cls=c.cls,
            time=float(self.time),
        )

    def describe(self) -> str:
        """``gripper 12.0 mm from head (person: needs 50 mm)``."""
        c = self.check
        kind = "inside" if c.cls == "zone" and c.other.startswith("keep_in ") else "from"
        return (
            f"{c.body} {self.distance * 1e3:.1f} mm {kind} {c.other} "
            f"({c.cls}: needs {c.required * 1e3:.0f} mm)"
        )


class Probe(NamedTuple):
    """One configuration as :meth:`CollisionModel.probe` sees it.

    Attributes:
        best: the tightest check.
        free: per moving body, its smallest margin (never below 0) [m].
        reach: per joint and moving body, the farthest the body is from the joint's
            axis [m], shape (6, bodies): the body moves no faster than
            ``|qd| @ reach`` [m/s].
        keep_in: the tightest margin inside a keep-in zone [m] (inf: none, or left out).
    """

    best: Clearance
    free: np.ndarray
    reach: np.ndarray
    keep_in: float = math.inf
