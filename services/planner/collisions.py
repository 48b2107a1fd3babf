"""The planner's collision check: every trajectory it returns, against the scene.

The whole curve (after any time stretching) is swept by :func:`manus.sweep.sweep`:
distances at a few configurations, and bounds of how far each body can have travelled
that prove the stretches in between (a violation shallower than 2 mm can hide only in
a stretch shorter than that; the smallest clearance is within 10 mm). A violation
refuses the plan as ``collision``, naming the segment (its knots: via points and lines), the
time, the arm body, the object and the distance; otherwise the smallest clearance goes
into the trajectory.
"""

from __future__ import annotations

import numpy as np

from manus.collision import CollisionModel
from manus.sweep import sweep
from schemas.collision import ClearanceReport
from services.planner.errors import refuse
from services.planner.labels import KnotLabels
from services.planner.spline import PiecewisePolynomial


def check_collisions(
    model: CollisionModel, curve: PiecewisePolynomial, labels: KnotLabels
) -> ClearanceReport:
    """Sweep ``curve`` through ``model``; the smallest clearance, or a refusal.

    Raises:
        PlanningError: ``collision`` with the segment, line, time, body, object, distance.
    """
    ex = curve.extremes(1)
    peaks = np.maximum(np.abs(ex.low), np.abs(ex.high))
    found = sweep(model, curve.times, peaks, curve.evaluate)
    bad = found.violation
    if bad is not None:
        seg = int(
            np.clip(np.searchsorted(curve.times, bad.time, side="right") - 1, 0, len(curve.h) - 1)
        )
        scene = model.scene
        version = f" (scene version {scene.version}: {scene.source})" if scene is not None else ""
        raise refuse(
            "collision",
            f"{labels.between(seg)}: at t = {bad.time:.3f} s the {bad.describe()}{version}",
            via_point=labels.via_indices[seg + 1],
            line=labels.lines[seg + 1],
            value=float(bad.distance),
            limit=float(bad.check.required),
        )
    return found.worst.report()
