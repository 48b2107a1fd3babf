"""Fast, conservative validity checks of configurations and motions (for sampling planners).

:class:`ValidityChecker` answers the questions of OMPL's ``StateValidityChecker`` and
``MotionValidator`` for the checks of a :class:`manus.collision.CollisionModel` (the arm
against itself, the scene's objects and zones, with each class's clearance) in a few
microseconds, where Coal takes 30-70: compiled kernels (:mod:`manus.validity_kernels`,
numba) over a cover of each arm body by convex pieces and lower bounds of the distances
(see that module). It is **conservative**: a margin it reports is never above the exact
one, so a configuration it calls valid is valid for Coal too; it may call a
configuration invalid that Coal finds clear (by at most a few millimetres of margin
near an obstacle: ``manus bench validity`` counts how often).

The pairs checked are exactly the model's (:attr:`CollisionModel.checks`) and its
keep-in zones (the same cover points and radii as the model), the objects the arm holds
included (:attr:`CollisionModel.held`: bodies of the model like the arm's, their pairs
with the arm's moving bodies shared the same way, :mod:`manus.validity_kernels`). Built
from a model, so a changed scene or held object means a new model and a new checker
(:func:`checker_for` keeps one per model); a changed gripper opening of the model, and a
scene object it moved (:attr:`CollisionModel.moved`), are followed on the next call.

First use compiles the kernels (or loads them from numba's cache, next to this module's
source): :meth:`ValidityChecker.__init__` does it, so build the checker at a service's
start, never in a control cycle (``manus bench validity`` reports the cost).
"""

from __future__ import annotations

import math
from typing import Any, NamedTuple

import numpy as np

from manus import motion_kernels
from manus import validity_kernels as k
from manus.clearance import Check
from manus.collision import CollisionModel
from manus.collision_pairs import STATIC_BODIES
from manus.config import ArmConfig
from manus.validity_arrays import SLACK_M, KernelArrays, Shaped, kernel_arrays
from manus.validity_scene import Obstacles, obstacles, place_moved

MOTION_FLOOR_M = 0.0005
"""Along a motion, a configuration whose margin bound is below this [m] ends the proof:
the motion counts as invalid there (each step of the proof is at least this long)."""

MAX_STEPS = 2000
"""Most steps of one motion check (a motion that needs more counts as invalid)."""

_WARM = False
"""Whether this process has compiled (or loaded) the kernels."""

__all__ = [
    "MAX_STEPS",
    "MOTION_FLOOR_M",
    "SLACK_M",
    "BatchMargins",
    "Margins",
    "MotionCheck",
    "ValidityChecker",
    "checker_for",
    "warm_up",
]

_Built = tuple[list[Shaped], Obstacles, KernelArrays]
"""What is kept per gripper opening: the bodies' shapes, the obstacles, the arrays."""


class Margins(NamedTuple):
    """Lower bounds of the margins of one configuration.

    Attributes:
        free: per body of :attr:`ValidityChecker.bodies`, its smallest margin [m] (inf:
            nothing to keep clear of), shape (B,).
        tight: the smallest margin of all [m] (< 0: not proven valid).
        check: the check it belongs to.
    """

    free: np.ndarray
    tight: float
    check: Check


class BatchMargins(NamedTuple):
    """:class:`Margins` of many configurations (n of them).

    Attributes:
        free: shape (n, B) [m].
        tight: shape (n,) [m].
        which: per configuration, (body, other) of the tightest check, shape (n, 2);
            :meth:`ValidityChecker.check_of` names it.
    """

    free: np.ndarray
    tight: np.ndarray
    which: np.ndarray


class MotionCheck(NamedTuple):
    """A motion's verdict.

    Attributes:
        ok: the whole straight joint-space motion is proven valid.
        fraction: where the proof stopped (0..1; 1.0 when ``ok``).
    """

    ok: bool
    fraction: float


class ValidityChecker:
    """The checks of ``model`` as compiled lower bounds (see the module docstring).

    Args:
        model: the collision model (scene, zones, clearances, gripper opening).
    """

    def __init__(self, model: CollisionModel) -> None:
        self.model = model
        pm = model.model
        self._placements = np.array([pm.jointPlacements[j].homogeneous for j in range(pm.njoints)])
        moving = [i for i, s in enumerate(model.shapes) if s.name not in STATIC_BODIES]
        self.bodies: list[str] = [model.shapes[i].name for i in moving]
        """The bodies checked, in the order of :attr:`Margins.free`."""
        self._joint_of = [int(model.geom.geometryObjects[i].parentJoint) for i in moving]
        self._shape_of: list[Shaped] = [self._shape(i) for i in moving]
        self._obstacles = obstacles(model, self.bodies)
        self._others = self._obstacles.others
        self._opening, self._moved = model.opening, model.moved.version
        self._by_opening: dict[float, _Built] = {}
        """The arrays built per gripper opening while no object moved (a gripper that
        closes and opens again: the same arrays, not built again; at most 8)."""
        self._build()

    # --- building ----------------------------------------------------------------------------

    def _shape(self, index: int) -> Shaped:
        shape = self.model.shapes[index]
        obj = self.model.geom.geometryObjects[index]
        size = shape.size
        if shape.name == "gripper":
            size = tuple(2.0 * float(v) for v in obj.geometry.halfSide)  # the opening now
        return shape.kind, size, np.asarray(obj.placement.homogeneous)

    def _build(self) -> None:
        """The kernels' arrays from the bodies, the obstacles and the keep-in zones."""
        built = self._by_opening.get(self._opening) if self.model.moved.version == 0 else None
        if built is None:
            built = self._arrays(list(self._shape_of), self._obstacles)
        _, _, arrays = built
        self._arm, self._scene, self._zone_checks, self._lever_table = arrays
        self._fresh_scratch()
        self._warm_up()

    def _arrays(self, shaped: list[Shaped], found: Obstacles) -> _Built:
        """The arrays for the bodies shaped as ``shaped`` and the obstacles ``found``,
        kept for the model's opening now while no object moved (at most 8 openings)."""
        arrays = kernel_arrays(
            self.model, self._placements, shaped, self._joint_of, self.bodies, found
        )
        built = (shaped, found, arrays)
        if self.model.moved.version == 0:
            if len(self._by_opening) >= 8:
                self._by_opening.clear()
            self._by_opening[self.model.opening] = built
        return built

    def prepare(self, opening: float) -> None:
        """Build now the arrays for gripper ``opening`` [m] (clamped as the model clamps
        it), kept as a rebuild keeps them: when the model's opening becomes that, the
        check takes them instead of building (about 1 ms) in that call. Nothing changes
        meanwhile (nothing is kept while an object is moved, as then the arrays follow
        it); the model's opening is set back as it was."""
        model = self.model
        was = model.opening
        model.set_opening(opening)
        try:
            key = model.opening
            if key == self._opening or key in self._by_opening or model.moved.version != 0:
                return
            shaped = list(self._shape_of)
            shaped[self.bodies.index("gripper")] = self._shape(model.body_index["gripper"])
            self._arrays(shaped, obstacles(model, self.bodies))
        finally:
            model.set_opening(was)

    def _fresh_scratch(self) -> None:
        """The kernels' work arrays, as new (one holds each body's nearest obstacle last
        time: a new check starts without it)."""
        n, B = len(self._arm[3]), len(self.bodies)
        m = len(self._arm[14])
        self._scratch = (
            np.zeros((self._placements.shape[0], 4, 4)),
            np.zeros((n, 3)),
            np.zeros((n, 3, 3)),
            np.zeros((B, 3)),
            np.zeros((m, 3)),
            np.zeros(3),
            np.full(B, -1, dtype=np.int64),  # per body, the obstacle nearest last time
        )
        self._free = np.empty(B)
        self._levers = np.empty((self._placements.shape[0] - 1, B))

    def _warm_up(self) -> None:
        """Compile (or load) every kernel now, once per process: the first call costs
        up to seconds."""
        global _WARM
        if _WARM:
            return
        _WARM = True
        q = np.zeros(self._placements.shape[0] - 1)
        self.is_valid(q)
        self.margins(q)
        self.is_valid_batch(q[None])
        self.margins_batch(q[None])
        self.motion_valid(q, q)
        self.reach(q)
        self.reach_batch(q[None])
        self.anchor_into(q, self._free, self._levers)
        motion_kernels.proven(q, self._free, self._levers, q[None])
        motion_kernels.proven_ahead(q, self._free, self._levers, q, q, q, np.eye(6), 0.06, 0.12)
        motion_kernels.stretch_bounds(
            np.zeros((1, 6)), np.zeros((2, 1)), np.zeros((2, 6, 1)), np.empty(1), np.empty(1)
        )
        arrays = (self._arm, self._scene, self._scratch, self._free, self._levers, math.inf)
        motion_kernels.motion(q, q + 1e-3, -math.inf, 1, *arrays)  # past the margins: too

    def _follow_opening(self) -> None:
        self._moved = place_moved(self.model, self._obstacles, self._scene, self._moved)
        if self.model.opening != self._opening:
            self._opening = self.model.opening
            built = self._by_opening.get(self._opening) if self._moved == 0 else None
            if built is not None:  # the arrays of a rebuild, as they were for this opening
                shapes, self._obstacles, _ = built
                self._shape_of = list(shapes)
            else:
                gripper = self.bodies.index("gripper")
                self._shape_of[gripper] = self._shape(self.model.body_index["gripper"])
                self._obstacles = obstacles(self.model, self.bodies)  # the gripper as a mover
            self._build()

    # --- questions -------------------------------------------------------------------------

    def is_valid(self, q: np.ndarray) -> bool:
        """Whether ``q`` [rad] (6,) is proven to keep every clearance."""
        self._follow_opening()
        return bool(k.valid(_f64(q), self._arm, self._scene, self._scratch))

    def is_valid_batch(self, Q: np.ndarray) -> np.ndarray:
        """:meth:`is_valid` of each row of ``Q`` [rad] (n, 6), shape (n,) bool."""
        self._follow_opening()
        Q = _f64(np.atleast_2d(Q))
        out = np.empty(len(Q), dtype=np.bool_)
        k.valid_batch(Q, self._arm, self._scene, self._scratch, out)
        return out

    def clearance_lower_bound(self, q: np.ndarray) -> float:
        """The smallest margin at ``q`` [rad], at most the exact one [m] (< 0: not
        proven valid)."""
        return self.margins(q).tight

    def margins(self, q: np.ndarray, cap: float = math.inf) -> Margins:
        """Lower bounds of each body's margin and the tightest check at ``q`` [rad], each
        at most ``cap`` [m] (a finite cap skips the pairs that cannot come under it:
        cheaper; a margin at the cap names no check)."""
        self._follow_opening()
        free = np.empty(len(self.bodies))
        tight, body, other = k.margins(_f64(q), self._arm, self._scene, self._scratch, free, cap)
        return Margins(free, float(tight), self.check_of(int(body), int(other)))

    def margins_batch(self, Q: np.ndarray, cap: float = math.inf) -> BatchMargins:
        """:meth:`margins` of each row of ``Q`` [rad] (n, 6), each at most ``cap`` [m]
        (a finite cap skips the pairs that cannot come under it: cheaper; a margin at
        the cap names no check)."""
        self._follow_opening()
        Q = _f64(np.atleast_2d(Q))
        free = np.empty((len(Q), len(self.bodies)))
        tight = np.empty(len(Q))
        which = np.empty((len(Q), 2), dtype=np.int64)
        k.margins_batch(Q, self._arm, self._scene, self._scratch, free, tight, which, cap)
        return BatchMargins(free, tight, which)

    def reach(self, q: np.ndarray) -> np.ndarray:
        """Per joint and body, the farthest any point of the body is from the joint's
        axis at ``q`` [m], shape (6, B): a body moves no faster than ``|qd| @ reach``."""
        self._follow_opening()
        k.pose(_f64(q), self._arm, self._scratch)
        out = np.empty((self._placements.shape[0] - 1, len(self.bodies)))
        motion_kernels.reach(self._arm, self._scratch, out)
        return out

    def anchor_into(self, q: np.ndarray, free: np.ndarray, reach: np.ndarray) -> float:
        """:meth:`margins` (into ``free`` (B,)) and :meth:`reach` (into ``reach`` (6, B))
        at ``q`` [rad] (float64) in one call; returns the tightest margin [m]."""
        self._follow_opening()
        return float(motion_kernels.anchor(q, self._arm, self._scene, self._scratch, free, reach))

    def reach_batch(self, Q: np.ndarray) -> np.ndarray:
        """:meth:`reach` at each row of ``Q`` [rad] (n, 6), shape (n, 6, B) [m]."""
        self._follow_opening()
        Q = _f64(np.atleast_2d(Q))
        out = np.empty((len(Q), self._placements.shape[0] - 1, len(self.bodies)))
        motion_kernels.reach_batch(Q, self._arm, self._scratch, out)
        return out

    def levers(self) -> np.ndarray:
        """Per joint and body, the farthest any point of the body can ever be from the
        joint's origin [m], shape (6, B) (0: the joint does not move it): whatever the
        configuration, a body moves no faster than ``|qd| @ levers``."""
        return self._lever_table

    def motion_valid(
        self,
        q0: np.ndarray,
        q1: np.ndarray,
        floor: float = MOTION_FLOOR_M,
        cap: float = math.inf,
    ) -> MotionCheck:
        """Whether the straight joint-space motion ``q0`` -> ``q1`` [rad] keeps every
        clearance, proven continuously (conservative advancement: no point of a body
        travels further than its margin between two configurations checked); a margin
        below ``floor`` [m] on the way counts as invalid. ``cap`` [m]: margins above it
        are not computed (each step is cheaper, the steps no longer than the cap)."""
        self._follow_opening()
        t = motion_kernels.motion(
            _f64(q0),
            _f64(q1),
            floor,
            MAX_STEPS,
            self._arm,
            self._scene,
            self._scratch,
            self._free,
            self._levers,
            cap,
        )
        return MotionCheck(t >= 1.0, min(float(t), 1.0))

    def check_of(self, body: int, other: int) -> Check:
        """The check of ``body`` (-1: a static body) and ``other`` (obstacle, or keep-in
        zone after the obstacles) as the kernels number them."""
        if other < 0:
            return Check("", "", "self", 0.0)
        if other >= len(self._others):
            zone = self._zone_checks[other - len(self._others)]
            return zone._replace(body=self.bodies[body] if body >= 0 else "base")
        name, cls, required = self._others[other]
        return Check(self.bodies[body], name, cls, required)


def warm_up() -> None:
    """Compile (or load from numba's cache) every kernel of the fast check now, in this
    process: what a service's start or a test session pays once (seconds with an empty
    cache, under one with a filled one), never a control cycle."""
    ValidityChecker(CollisionModel(None, ArmConfig()))


def checker_for(model: CollisionModel) -> ValidityChecker:
    """The model's checker, built once per model and kept by it (:attr:`CollisionModel.
    derived`: a table keyed by the model whose values refer to their key would keep every
    model alive for the whole process)."""
    found = model.derived.get("validity")
    if not isinstance(found, ValidityChecker):
        found = model.derived["validity"] = ValidityChecker(model)
    return found


def _f64(a: Any) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=np.float64)
