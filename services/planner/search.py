"""Joint-space search with OMPL (the ``ompl`` package's official bindings): a path of
joint configurations from the start to one of the goal states, around everything the
:class:`~services.planner.validity.Validity` knows.

1. **Direct**: the straight joint-space motion to each of the :data:`DIRECT_TRIES`
   nearest goal states; the first that is clear is the path (most goals need no search).
2. **Search**: OMPL's RRTConnect (:data:`PLANNER`; chosen by measurement, docs/reach.md)
   in the box the start and goals span, widened by :data:`BOX_MARGIN` and cut to the
   joint limits; every goal state is a goal (``GoalStates``). Which configurations and
   motions are valid is :class:`~services.planner.floors.Floors`' business (the scene
   with a padding, the arm's work area).
3. **Simplification**: OMPL's shortcuts (partial shortcuts, vertex reduction, collapsing
   close vertices), then two passes of our own: from each vertex, the farthest one it
   sees (:func:`greedy_shortcut`); from each vertex, a straight motion to the goal state
   that makes the path shortest (:func:`nearer_goal`).

**Determinism.** OMPL draws every random number from generators seeded, as each is
created, by one process-wide seed generator, which :func:`ompl.util.RNG.setSeed`
reseeds (OMPL logs an error when that happens after the first seeds were drawn; it is
silenced here). Each search reseeds it with the request's seed and creates its planner,
sampler and simplifier afresh, under :data:`_LOCK` (a live shell plans on several
threads): the same start, goals, scene and seed give the same path, bit for bit. The
search stops after a number of iterations (``budget``), never after a time, so a slow
machine finds the same path, later.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Callable
from typing import NamedTuple

import numpy as np
from ompl import base as ob
from ompl import geometric as og
from ompl import util as ou

from services.planner.floors import Floors
from services.planner.validity import Validity
from services.planner.work_area import WorkArea

PLANNER = "RRTConnect"
"""The OMPL planner used (see docs/reach.md, Choosing the planner, for the measurement)."""

DIRECT_TRIES = 4
"""Nearest goal states tried with a straight motion before any search."""

BOX_MARGIN = math.pi / 2
"""How far beyond the range the start and the goals span each joint may go [rad]."""

SIMPLIFY_ROUNDS = 5
"""Most rounds of OMPL's shortcutting (it stops earlier when a round changes nothing)."""

RANGE = 1.0
"""Longest motion the search adds in one step [rad] (measured: docs/reach.md)."""

SEARCHES = 3
"""Most independent searches per plan, the shortest path kept (measured: docs/reach.md):
more only while the path found is a detour (:data:`DETOUR`)."""

DETOUR = 1.3
"""A path longer than this times the straight joint-space distance to the nearest goal
state is a detour: another search is made (up to :data:`SEARCHES`)."""

SEED_STRIDE = 1_000_003
"""Seed step between the searches of one plan."""

_LOCK = threading.Lock()
"""One search at a time in a process: OMPL's seed generator is process-wide."""


class SearchSettings(NamedTuple):
    """How a search runs.

    Attributes:
        seed: the seed of every random number the search draws (>= 1).
        budget: most iterations (samples) of the search before it gives up [-].
        padding: margin kept beyond the clearances away from the start and goal [m].
        planner: the OMPL planner's name (``RRTConnect``; others for measurements).
        range: longest motion the planner adds in one step [rad] (0: OMPL's default,
            a fifth of the search box's diagonal; :data:`RANGE` by default).
        searches: most independent searches (seeds derived from ``seed``; more only for
            a detour), the shortest path kept (:data:`SEARCHES` by default).
    """

    seed: int = 1
    budget: int = 3000
    padding: float = 0.005
    planner: str = PLANNER
    range: float = RANGE
    searches: int = SEARCHES


class Found(NamedTuple):
    """A path.

    Attributes:
        path: waypoints [rad], shape (n, 6), the start first and a goal state last.
        goal: index of the goal state reached.
        iterations: search iterations used (0: the direct motion).
    """

    path: np.ndarray
    goal: int
    iterations: int


class NotFound(NamedTuple):
    """How far a search got.

    Attributes:
        iterations: search iterations used [-].
        states: configurations in the start tree and in the goal tree [-].
        closest: the start-tree configuration nearest a goal state [rad], shape (6,).
        distance: its joint-space distance to that goal state [rad].
        goal: index of that goal state.
    """

    iterations: int
    states: tuple[int, int]
    closest: np.ndarray
    distance: float
    goal: int


def search(
    start: np.ndarray,
    goals: np.ndarray,
    validity: tuple[Validity, Validity],
    work: WorkArea | None,
    lower: np.ndarray,
    upper: np.ndarray,
    settings: SearchSettings,
) -> Found | NotFound:
    """A path from ``start`` to one of ``goals`` (see the module docstring).

    Args:
        start: start configuration [rad], shape (6,); within its clearances.
        goals: goal states [rad], shape (k, 6), nearest first; within their clearances.
        validity: the geometry: the fast check for the search, the exact one for the
            start and the goals.
        work: the arm's own work area (None: not kept).
        lower: lower joint limits [rad], shape (6,).
        upper: upper joint limits [rad], shape (6,).
        settings: seed, budget, padding, planner.
    """
    floors = Floors(validity[0], validity[1], work, settings.padding, [start, *goals])
    for k, goal in enumerate(goals[:DIRECT_TRIES]):
        if floors.motion(start, goal):
            return Found(np.array([start, goal]), k, 0)
    lo = np.maximum(lower, np.minimum(start, goals.min(axis=0)) - BOX_MARGIN)
    hi = np.minimum(upper, np.maximum(start, goals.max(axis=0)) + BOX_MARGIN)
    with _LOCK:
        return _Search(start, goals, floors, lo, hi, settings).run()


def _array(state: ob.State) -> np.ndarray:
    return np.array(state[0:6], dtype=float)


class _Motions(ob.MotionValidator):  # type: ignore[misc]
    """OMPL's motion validator, answered by :class:`Floors` (both ends included)."""

    def __init__(self, si: ob.SpaceInformation, floors: Floors) -> None:
        super().__init__(si)
        self.floors = floors

    def checkMotion(self, s1: ob.State, s2: ob.State) -> bool:  # noqa: N802 (OMPL's name)
        return self.floors.motion(_array(s1), _array(s2))


class _Search:
    """One OMPL search, its objects created afresh (see the module docstring)."""

    def __init__(
        self,
        start: np.ndarray,
        goals: np.ndarray,
        floors: Floors,
        lo: np.ndarray,
        hi: np.ndarray,
        settings: SearchSettings,
    ) -> None:
        self.start, self.goals, self.floors, self.settings = start, goals, floors, settings
        self.lo, self.hi = lo, hi
        self.iterations = 0

    def _budget(self) -> bool:
        self.iterations += 1
        return self.iterations > self.settings.budget

    def run(self) -> Found | NotFound:
        """A search; while its path is longer than :data:`DETOUR` times the straight
        distance to the nearest goal state (a detour: another search may find a shorter
        way), up to :attr:`SearchSettings.searches` in all, each with its own seed
        derived from the request's; the shortest path found (the first search's
        progress if none)."""
        level = ou.getLogLevel()
        ou.setLogLevel(ou.LOG_NONE)  # reseeding after the first search logs an error
        direct = float(np.linalg.norm(self.goals - self.start, axis=1).min())
        best: Found | NotFound | None = None
        used = 0
        try:
            for k in range(self.settings.searches):
                ou.RNG.setSeed(self.settings.seed + SEED_STRIDE * k)
                self.iterations = 0
                found = self._solve()
                used += min(self.iterations, self.settings.budget)
                if (
                    isinstance(found, Found)
                    and (not isinstance(best, Found) or _length(found.path) < _length(best.path))
                ) or best is None:
                    best = found
                if not isinstance(best, Found) or _length(best.path) <= DETOUR * direct:
                    break
        finally:
            ou.setLogLevel(level)
        assert best is not None
        return best._replace(iterations=used)

    def _solve(self) -> Found | NotFound:
        space = ob.RealVectorStateSpace(6)
        bounds = ob.RealVectorBounds(6)
        for j in range(6):
            bounds.setLow(j, float(self.lo[j]))
            bounds.setHigh(j, float(self.hi[j]))
        space.setBounds(bounds)
        si = ob.SpaceInformation(space)
        floors = self.floors
        si.setStateValidityChecker(lambda s: floors.state(_array(s)))
        motions = _Motions(si, floors)
        si.setMotionValidator(motions)
        si.setup()
        pdef = ob.ProblemDefinition(si)
        pdef.addStartState(_state(space, self.start))
        goal = ob.GoalStates(si)
        for q in self.goals:
            goal.addState(_state(space, q))
        pdef.setGoal(goal)
        planner = _planner(self.settings.planner, si)
        if self.settings.range > 0.0:
            planner.setRange(self.settings.range)
        planner.setProblemDefinition(pdef)
        planner.setup()
        status = planner.solve(ob.PlannerTerminationCondition(self._budget))
        exact = status.getStatus() == ob.PlannerStatus.EXACT_SOLUTION
        if not exact:
            return self._not_found(pdef, planner, si)
        path = pdef.getSolutionPath()
        simplifier = og.PathSimplifier(si, goal)
        for _ in range(SIMPLIFY_ROUNDS):
            changed = simplifier.partialShortcutPath(path)
            changed = simplifier.reduceVertices(path) or changed
            changed = simplifier.collapseCloseVertices(path) or changed
            if not changed:
                break
        waypoints = np.array([_array(path.getState(i)) for i in range(path.getStateCount())])
        waypoints = greedy_shortcut(waypoints, floors.motion)
        waypoints = nearer_goal(waypoints, self.goals, floors.motion)
        end = int(np.argmin(np.abs(self.goals - waypoints[-1]).max(axis=1)))
        return Found(waypoints, end, self.iterations)

    def _not_found(
        self, pdef: ob.ProblemDefinition, planner: ob.Planner, si: ob.SpaceInformation
    ) -> NotFound:
        data = ob.PlannerData(si)
        planner.getPlannerData(data)
        tags = [data.getVertex(i).getTag() for i in range(data.numVertices())]
        states = (tags.count(1), tags.count(2))
        closest, distance, k = self.start, math.inf, 0
        if pdef.hasApproximateSolution():
            path = pdef.getSolutionPath()
            closest = _array(path.getState(path.getStateCount() - 1))
        gaps = np.linalg.norm(self.goals - closest, axis=1)
        k = int(np.argmin(gaps))
        distance = float(gaps[k])
        return NotFound(min(self.iterations, self.settings.budget), states, closest, distance, k)


def _state(space: ob.RealVectorStateSpace, q: np.ndarray) -> ob.State:
    state = space.allocState()
    state[0:6] = [float(v) for v in q]
    return state


def _planner(name: str, si: ob.SpaceInformation) -> ob.Planner:
    """The OMPL planner called ``name`` (a geometric planner's class name)."""
    make: Callable[[ob.SpaceInformation], ob.Planner] | None = getattr(og, name, None)
    if make is None:
        raise ValueError(f"no OMPL geometric planner named {name!r}")
    return make(si)


def greedy_shortcut(
    path: np.ndarray, clear: Callable[[np.ndarray, np.ndarray], bool]
) -> np.ndarray:
    """From each kept waypoint, jump to the farthest later one it reaches in a straight
    motion (``clear``), shape (m, 6) with m <= n; the ends are kept."""
    kept = [0]
    i = 0
    while i < len(path) - 1:
        j = len(path) - 1
        while j > i + 1 and not clear(path[i], path[j]):
            j -= 1
        kept.append(j)
        i = j
    return np.asarray(path[kept])


def nearer_goal(
    path: np.ndarray, goals: np.ndarray, clear: Callable[[np.ndarray, np.ndarray], bool]
) -> np.ndarray:
    """``path`` ending at whichever goal state makes it shortest: from each waypoint, a
    straight motion to any goal state (``clear``) that shortens the whole path replaces
    the rest of it (the search reaches the goal state it happens to connect to first)."""
    steps = np.linalg.norm(np.diff(path, axis=0), axis=1)
    walked = np.concatenate([[0.0], np.cumsum(steps)])
    best, best_length = path, float(walked[-1])
    for i in range(len(path) - 1):
        gaps = np.linalg.norm(goals - path[i], axis=1)
        for k in np.argsort(gaps, kind="stable"):
            total = float(walked[i] + gaps[k])
            if total >= best_length - 1e-9:
                break
            if clear(path[i], goals[k]):
                best, best_length = np.vstack([path[: i + 1], goals[k]]), total
                break
    return np.asarray(best)


def _length(path: np.ndarray) -> float:
    """Joint-space length of a path of waypoints [rad]."""
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
