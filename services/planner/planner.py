"""The planner interface: one kind of motion in, the same :class:`Trajectory` out.

Each kind of motion a plan request may ask for (:data:`schemas.planning.MOTIONS`) is
served by one :class:`Planner` subclass, listed in :data:`services.planner.registry.
PLANNERS`. The cut follows OMPL's (goal representation, validity, search, simplification,
time parametrisation behind small interfaces) and Pilz's (PTP, LIN and CIRC trajectory
generators behind one base class that does the shared work):

- :meth:`Planner.route` is the kind's own part: where the knots go and when (a path's
  via points solved on the start's IK branch; a goal's search and simplification), the
  curve through them, and the checks that belong to that kind only (for a via-point path:
  the IK branch and the wrist singularity along the curve). It returns a :class:`Route`,
  whose :class:`~services.planner.labels.KnotLabels` say what each knot is. A request
  with ``resume`` asks the same planner for what is left of a plan it made.
- :meth:`Planner.plan` adds what every kind shares and no kind overrides: the joint speed
  and acceleration limits (refused, or time stretched uniformly when the route asks for
  it: :func:`~services.planner.checks.check_rates`), the collision sweep of the final
  curve through the scene in use (:func:`~services.planner.collisions.check_collisions`),
  and the :class:`Trajectory` (knots, what each is, their Cartesian positions, the
  preview).

A refusal anywhere is a :class:`~services.planner.errors.PlanningError` naming the knot or
segment by its labels. No clock, no randomness, no I/O: a planner that searches takes its
randomness from a seeded generator in its config.
"""

from __future__ import annotations

import math
import threading
from abc import ABC, abstractmethod
from typing import Any, Generic, NamedTuple, Protocol, TypeVar

import numpy as np

from manus.collision import CollisionModel
from manus.kinematics import fk_batch
from schemas.collision import ClearanceReport
from schemas.motion import Motion
from schemas.planning import PlanResume, Trajectory
from services.planner.checks import RateCheck, check_rates
from services.planner.collisions import check_collisions
from services.planner.config import PlannerConfig
from services.planner.labels import KnotLabels
from services.planner.spline import PiecewisePolynomial

M = TypeVar("M", bound=Motion)


class SceneInUse(Protocol):
    """The scene every plan is checked against (the core holds it, a scene update
    replaces it)."""

    collision: CollisionModel | None
    """The collision model (None: no scene, no check)."""
    checking: threading.Lock
    """Held while the model is used: its Pinocchio data is scratch space shared by every
    check, and a live shell plans on several threads."""


class Route(NamedTuple):
    """A kind's own part of a plan: knots, the curve through them, what each knot is.

    Attributes:
        times: knot times [s], shape (n,), from 0, strictly increasing.
        knots: joint positions at the knots [rad], shape (n, 6); row 0 is the start.
        velocities: joint velocities at the knots [rad/s], shape (n, 6).
        accelerations: joint accelerations at the knots [rad/s^2], shape (n, 6), or None
            (cubic segments).
        curve: the Hermite curve through them (:meth:`PiecewisePolynomial.hermite`).
        labels: what each knot is.
        speed_scaling: stretch time to respect the joint limits instead of refusing.
        notes: what the planner wants the user to know.
    """

    times: np.ndarray
    knots: np.ndarray
    velocities: np.ndarray
    accelerations: np.ndarray | None
    curve: PiecewisePolynomial
    labels: KnotLabels
    speed_scaling: bool
    notes: list[str]


class Planner(ABC, Generic[M]):
    """Plans one kind of motion (see the module docstring).

    Args:
        config: the arm model and the planning margins.
    """

    def __init__(self, config: PlannerConfig) -> None:
        self.config = config

    @abstractmethod
    def route(
        self, motion: M, start: np.ndarray, resume: PlanResume | None, scene: SceneInUse
    ) -> Route:
        """The knots and the curve of ``motion`` from ``start``, checked as this kind needs.

        Args:
            motion: what to plan.
            start: the start configuration [rad], shape (6,), finite.
            resume: a paused plan of this planner's to go on with from ``start`` (None:
                plan the whole motion).
            scene: the scene in use (for a planner whose search needs it; the final
                sweep is :meth:`plan`'s).

        Raises:
            PlanningError: the motion cannot be planned, naming where and why.
        """

    def plan(
        self,
        motion: M,
        start: np.ndarray,
        *,
        resume: PlanResume | None,
        preview_dt: float,
        scene: SceneInUse,
    ) -> Trajectory:
        """The trajectory of ``motion`` from ``start``: :meth:`route`, then the stages
        every kind shares (limits, collision sweep, the message).

        Args:
            motion: what to plan.
            start: the start configuration [rad], shape (6,), finite.
            resume: a paused plan to go on with (None: the whole motion).
            preview_dt: step of the Cartesian preview [s] (0: none).
            scene: the scene in use.

        Raises:
            PlanningError: naming where and why.
        """
        route = self.route(motion, start, resume, scene)
        moving = bool(route.velocities[0].any() or route.velocities[-1].any())
        rates = check_rates(
            route.curve,
            route.labels,
            self.config,
            speed_scaling=route.speed_scaling,
            moving_ends=moving,
        )
        clearance, version = None, -1
        with scene.checking:
            if scene.collision is not None:
                clearance = check_collisions(scene.collision, rates.curve, route.labels)
                version = scene.collision.scene.version if scene.collision.scene else -1
        return self._trajectory(route, rates, clearance, version, preview_dt)

    def _trajectory(
        self,
        route: Route,
        rates: RateCheck,
        clearance: ClearanceReport | None,
        version: int,
        preview_dt: float,
    ) -> Trajectory:
        k = rates.time_scale
        duration = rates.curve.duration
        step = 0.0
        preview_t: np.ndarray = np.zeros(0)
        if preview_dt > 0.0:
            step = max(preview_dt, duration / (self.config.max_preview_points - 1))
            preview_t = np.arange(math.floor(duration / step) + 1) * step
            if duration - preview_t[-1] > 1e-9:
                preview_t = np.append(preview_t, duration)
        n = len(route.knots)
        # One FK call for the knots and the preview.
        points = np.vstack([route.knots, rates.curve.evaluate(preview_t)])
        xyz = fk_batch(points, self.config.arm)[:, :3, 3]
        labels = route.labels
        acc = route.accelerations
        return Trajectory(
            times=_rows(route.times * k),
            positions=_rows(route.knots),
            velocities=_rows(route.velocities / k),
            accelerations=[] if acc is None else _rows(acc / (k * k)),
            via_xyz=_rows(xyz[:n]),
            via_lines=list(labels.lines),
            knot_kinds=[str(kind) for kind in labels.kinds],
            via_indices=list(labels.via_indices),
            preview_xyz=_rows(xyz[n:]),
            preview_dt=step,
            time_scale=k,
            notes=[*route.notes, *rates.notes],
            clearance=clearance,
            scene_version=version,
        )


def _rows(a: np.ndarray) -> list[Any]:
    """Plain floats for the message (a list, or a list of rows)."""
    out: list[Any] = np.asarray(a, dtype=float).tolist()
    return out
