"""What the goal planners know of the arm's geometry: one small interface, OMPL's cut.

OMPL keeps the robot behind a ``StateValidityChecker`` (one configuration) and a
``MotionValidator`` (between two); the search (:mod:`.search`), the goal states
(:mod:`.goal_states`) and the straight line (:mod:`.line`) ask only a :class:`Validity`:

- :meth:`Validity.margins`: per moving arm body, its margin at ``q`` (distance minus the
  class clearance to the nearest thing it must keep clear of, the keep-in zone included)
  and the tightest check (negative: violated);
- :meth:`Validity.motion`: whether the straight joint-space motion between two
  configurations keeps every margin at or above a floor, proven, not sampled: a motion
  it calls valid is valid;
- :meth:`Validity.explain`: the tightest check at ``q``, for a refusal's message.

:class:`FastValidity` answers from the compiled, conservative check
(:class:`manus.validity.ValidityChecker`: lower bounds of the margins, a few
microseconds a configuration, motions proven by conservative advancement in compiled
code); the search uses it. Its bounds may lie a few millimetres below the exact margins
near an obstacle, so the goal states and the start, which may lie that close, are judged
by :class:`CoalValidity`, the exact model:

:class:`CoalValidity` answers with today's exact model (:class:`manus.collision.
CollisionModel`, Coal) and proves motions by conservative advancement: a body cannot
lose more margin than its points travel, and no point of it travels further than the
joint moves times the joints' levers to it (:class:`manus.travel.BodyPoints`); a
stretch whose two ends leave together more margin than that travel is clear, any
other is halved, down to :data:`RESOLUTION_M` of travel, below which the motion is
called invalid (a motion that grazes its floor more closely than that is refused).
"""

from __future__ import annotations

import math
from typing import NamedTuple, Protocol

import numpy as np

from manus.clearance import Clearance
from manus.collision import CollisionModel
from manus.travel import BodyPoints
from manus.validity import MOTION_FLOOR_M, checker_for

_PROBES = np.array([0.5, 0.25, 0.75])
"""Where :meth:`FastValidity.motion` looks first, as fractions of the motion."""

MOTION_CAP_M = 0.05
""":meth:`FastValidity.motion` computes no margin more than this above its floor [m]:
each step of its advancement is cheaper (measured: a fifth less time per plan), no step
longer than this."""

RESOLUTION_M = 0.001
"""Shortest stretch of a motion (of any point's travel bound) [m] that is halved again;
one still unproven there makes the motion invalid."""


class Margins(NamedTuple):
    """One configuration as the planners see it.

    Attributes:
        per_body: each moving body's margin [m], shape (B,) (never below 0; inf: it has
            nothing to keep clear of).
        tightest: the smallest margin of any check [m] (< 0: violated).
    """

    per_body: np.ndarray
    tightest: float


class Validity(Protocol):
    """The geometry behind the planners (see the module docstring)."""

    def margins(self, q: np.ndarray, cap: float = math.inf) -> Margins:
        """Per-body margins and the tightest margin at ``q`` [rad], shape (6,); those
        above ``cap`` [m] may be given as ``cap`` (cheaper: the pairs that cannot come
        under it are skipped)."""
        ...

    def motion(self, qa: np.ndarray, qb: np.ndarray, floor: float) -> bool:
        """Whether every margin stays at or above ``floor`` [m] (>= 0) all along the
        straight joint-space motion from ``qa`` to ``qb`` [rad] (both ends included)."""
        ...

    def explain(self, q: np.ndarray) -> Clearance:
        """The tightest check at ``q`` [rad] (which body, which object, how far)."""
        ...

    def valid_many(self, Q: np.ndarray) -> np.ndarray:
        """Which of the configurations ``Q`` [rad], (m, 6), keep every clearance, (m,)."""
        ...


class CoalValidity:
    """:class:`Validity` from the exact collision model (Coal), with a cache of the
    configurations already asked (a search asks its tree's states again and again).

    Args:
        model: the collision model (the scene, the zones, the arm's own bodies).
        resolution: shortest stretch halved by :meth:`motion` [m] of travel.
    """

    def __init__(self, model: CollisionModel, resolution: float = RESOLUTION_M) -> None:
        self.model = model
        self.resolution = resolution
        points = BodyPoints(model)
        self._levers = points.levers  # (6, B)
        self._moves = points.moves  # (6, B)
        self._radius = points.radius  # (B,)
        self._cache: dict[bytes, Margins] = {}
        self.computed = 0
        """Configurations whose distances were computed (not taken from the cache) [-]."""

    def margins(self, q: np.ndarray, cap: float = math.inf) -> Margins:
        q = np.asarray(q, dtype=float)
        key = q.tobytes()
        found = self._cache.get(key)
        if found is None:
            probe = self.model.probe(q, reach=False)
            found = Margins(probe.free, float(probe.best.margin))
            if len(self._cache) > 100_000:
                self._cache.clear()
            self._cache[key] = found
            self.computed += 1
        return found

    def motion(self, qa: np.ndarray, qb: np.ndarray, floor: float) -> bool:
        qa, qb = np.asarray(qa, dtype=float), np.asarray(qb, dtype=float)
        ends = [self.margins(qa), self.margins(qb)]
        if any(m.tightest < floor for m in ends):
            return False
        delta = qb - qa
        step = np.abs(delta)
        travel = step @ self._levers + (step @ self._moves) * self._radius  # (B,) over s in [0, 1]
        widest = float(travel.max())
        stack = [(0.0, 1.0, ends[0].per_body - floor, ends[1].per_body - floor)]
        while stack:
            s0, s1, slack0, slack1 = stack.pop()
            span = s1 - s0
            if bool((slack0 + slack1 >= travel * span).all()):
                continue
            if widest * span <= self.resolution:
                return False
            mid = 0.5 * (s0 + s1)
            m = self.margins(qa + mid * delta)
            if m.tightest < floor:
                return False
            slack = m.per_body - floor
            stack.append((mid, s1, slack, slack1))
            stack.append((s0, mid, slack0, slack))
        return True

    def explain(self, q: np.ndarray) -> Clearance:
        return self.model.clearance(np.asarray(q, dtype=float))

    def valid_many(self, Q: np.ndarray) -> np.ndarray:
        return np.array([self.margins(q).tightest >= 0.0 for q in np.atleast_2d(Q)])


class FastValidity:
    """:class:`Validity` from the compiled conservative check of ``model``
    (:func:`manus.validity.checker_for`: built once per model; the first in a process
    loads or compiles its kernels).

    Args:
        model: the collision model.
    """

    def __init__(self, model: CollisionModel) -> None:
        self.model = model
        self.checker = checker_for(model)

    def margins(self, q: np.ndarray, cap: float = math.inf) -> Margins:
        found = self.checker.margins(q, cap)
        return Margins(np.maximum(found.free, 0.0), float(found.tight))

    def motion(self, qa: np.ndarray, qb: np.ndarray, floor: float) -> bool:
        floor = max(floor, MOTION_FLOOR_M)
        # A bound under the floor at one of a few samples refuses at once: most refused
        # motions (a search tries many) cost one batched call, not the advancement.
        samples = qa + _PROBES[:, None] * (np.asarray(qb) - qa)
        if bool((self.checker.margins_batch(samples, floor).tight < floor).any()):
            return False
        return bool(self.checker.motion_valid(qa, qb, floor, floor + MOTION_CAP_M).ok)

    def explain(self, q: np.ndarray) -> Clearance:
        return self.model.clearance(np.asarray(q, dtype=float))

    def valid_many(self, Q: np.ndarray) -> np.ndarray:
        return np.asarray(self.checker.is_valid_batch(np.atleast_2d(Q)))


class FreeSpace:
    """The :class:`Validity` without a scene (scene ``none``): every configuration and
    motion is clear, as in a via-point plan without a scene."""

    def margins(self, q: np.ndarray, cap: float = math.inf) -> Margins:
        return Margins(np.full(1, np.inf), np.inf)

    def motion(self, qa: np.ndarray, qb: np.ndarray, floor: float) -> bool:
        return True

    def explain(self, q: np.ndarray) -> Clearance:
        raise AssertionError("nothing to explain without a scene")  # pragma: no cover

    def valid_many(self, Q: np.ndarray) -> np.ndarray:
        return np.ones(len(np.atleast_2d(Q)), dtype=bool)
