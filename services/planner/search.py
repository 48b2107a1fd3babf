"""Joint-space search with OMPL (the ``ompl`` package's official bindings): a path of
joint configurations from the start to one of the goal states, around everything the
:class:`~services.planner.validity.Validity` knows.

1. **Direct**: the straight joint-space motion to each of the :data:`DIRECT_TRIES`
   nearest goal states; the first that is clear is the path (most goals need no search).
2. **Search**: OMPL's RRTConnect (:data:`PLANNER`; chosen by measurement, docs/reach.md)
   in the box the start and goals span, widened by :data:`BOX_MARGIN` and cut to the
   joint limits. First toward the nearest goal states only (within :data:`NEAR_GOALS`
   times the nearest one's joint distance; a third of the budget), then, if that finds
   nothing, toward every goal state with the rest of the budget: RRTConnect connects to
   whichever goal state its trees meet first, often a far IK branch. Which
   configurations and motions are valid is :class:`~services.planner.floors.Floors`'
   business (the scene with a padding, the arm's work area).
3. **Shortening** each path found (:mod:`.shortcuts`).
4. **Shorter paths**: while the path is longer than :data:`DETOUR` times the straight
   distance to the nearest goal state (it goes around something), up to
   :data:`SEARCHES` searches in all: each one for a path shorter than the best so far,
   within its informed set (:class:`~services.planner.informed.Informed`), with
   :data:`IMPROVE_BUDGET` iterations; the shortest path is kept, and shortened once more
   with a finer rope.

**Determinism.** OMPL draws every random number from generators seeded, as each is
created, by one process-wide seed generator, which :func:`ompl.util.RNG.setSeed`
reseeds (OMPL logs an error when that happens after the first seeds were drawn; it is
silenced here). Each search reseeds it with a seed derived from the request's and
creates its planner, sampler and simplifier afresh, under :data:`_LOCK` (a live shell
plans on several threads): the same start, goals, scene and seed give the same path, bit
for bit. Every search stops after a number of iterations, never after a time, so a slow
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
from services.planner.informed import Informed
from services.planner.shortcuts import (
    FINAL_ROPE_RAD,
    ROPE_RAD,
    path_length,
    shorten,
    simplify,
)
from services.planner.validity import Validity
from services.planner.work_area import WorkArea

PLANNER = "RRTConnect"
"""The OMPL planner used (see docs/reach.md, Choosing the planner, for the measurement)."""

DIRECT_TRIES = 4
"""Nearest goal states tried with a straight motion before any search."""

BOX_MARGIN = math.pi / 2
"""How far beyond the range the start and the goals span each joint may go [rad]."""

RANGE = 1.0
"""Longest motion the search adds in one step [rad] (measured: docs/reach.md)."""

NEAR_GOALS = 1.2
"""The first search goes to the goal states within this times the nearest one's joint
distance from the start."""

NEAR_BUDGET = 300
"""Most iterations of the first search (at most a third of the budget); then every goal
state is a goal."""

STOP_AFTER_FAILED = 2
"""Searches for a shorter path that find none before the plan stops looking."""

SEARCHES = 6
"""Most searches per plan: the first and those for a shorter path (measured:
docs/reach.md); more only while the path is a detour (:data:`DETOUR`)."""

DETOUR = 1.3
"""A path longer than this times the straight joint-space distance to the nearest goal
state is a detour: another search looks for a shorter one (up to :data:`SEARCHES`)."""

IMPROVE_BUDGET = 400
"""Most iterations of each search for a shorter path."""

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
        searches: most searches (the first and those for a shorter path, seeds derived
            from ``seed``; :data:`SEARCHES` by default, 1: the first path, shortened).
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


class _Problem(NamedTuple):
    """One OMPL problem: its space, the goal states, and what is valid in it."""

    si: ob.SpaceInformation
    space: ob.RealVectorStateSpace
    goal: ob.GoalStates


class _Search:
    """The searches of one plan, their objects created afresh (see the module docstring)."""

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
        self.iterations = 0  # of the running search
        self.cap = settings.budget  # its budget
        self.used = 0  # of every search

    def _budget(self) -> bool:
        self.iterations += 1
        return self.iterations > self.cap

    def run(self) -> Found | NotFound:
        """The first path, then shorter ones while it is a detour (see the module
        docstring); the shortest, shortened once more (the first search's progress if
        none was found)."""
        level = ou.getLogLevel()
        ou.setLogLevel(ou.LOG_NONE)  # reseeding after the first search logs an error
        try:
            ou.RNG.setSeed(self.settings.seed)
            best = self._first()
            if not isinstance(best, Found):
                return best
            direct = float(np.linalg.norm(self.goals - self.start, axis=1).min())
            failed = 0
            for k in range(1, self.settings.searches):
                length = path_length(best.path)
                if length <= DETOUR * direct or failed >= STOP_AFTER_FAILED:
                    break
                ou.RNG.setSeed(self.settings.seed + SEED_STRIDE * k)
                found = self._shorter(Informed(self.start, self.goals, length))
                if isinstance(found, Found) and path_length(found.path) < length:
                    best = found
                else:
                    failed += 1
            return self._final(best)._replace(iterations=self.used)
        finally:
            ou.setLogLevel(level)

    def _first(self) -> Found | NotFound:
        """Toward the nearest goal states with a third of the budget, then toward all."""
        budget = self.settings.budget
        gaps = np.linalg.norm(self.goals - self.start, axis=1)
        near = self.goals[gaps <= NEAR_GOALS * gaps.min()]
        if len(near) < len(self.goals):
            found = self._solve(near, self.lo, self.hi, min(NEAR_BUDGET, budget // 3), None)
            if isinstance(found, Found):
                return found
        return self._solve(self.goals, self.lo, self.hi, budget - self.used, None)

    def _shorter(self, informed: Informed) -> Found | NotFound | None:
        """A search for a path shorter than ``informed.length`` (None: no goal state is
        near enough to end one)."""
        if len(informed.goals) == 0:
            return None
        lo, hi = informed.box(self.lo, self.hi)
        return self._solve(informed.goals, lo, hi, IMPROVE_BUDGET, informed)

    def _problem(
        self, goals: np.ndarray, lo: np.ndarray, hi: np.ndarray, informed: Informed | None
    ) -> _Problem:
        space = ob.RealVectorStateSpace(6)
        bounds = ob.RealVectorBounds(6)
        for j in range(6):
            bounds.setLow(j, float(lo[j]))
            bounds.setHigh(j, float(hi[j]))
        space.setBounds(bounds)
        si = ob.SpaceInformation(space)
        floors = self.floors
        if informed is None:
            si.setStateValidityChecker(lambda s: floors.state(_array(s)))
        else:

            def valid(s: ob.State) -> bool:
                q = _array(s)
                return informed.contains(q) and floors.state(q)

            si.setStateValidityChecker(valid)
        si.setMotionValidator(_Motions(si, floors))
        si.setup()
        goal = ob.GoalStates(si)
        for q in goals:
            goal.addState(_state(space, q))
        return _Problem(si, space, goal)

    def _solve(
        self,
        goals: np.ndarray,
        lo: np.ndarray,
        hi: np.ndarray,
        budget: int,
        informed: Informed | None,
    ) -> Found | NotFound:
        """One OMPL search to ``goals`` in ``lo`` .. ``hi`` [rad] within ``budget``
        iterations, its path shortened (:mod:`.shortcuts`)."""
        problem = self._problem(goals, lo, hi, informed)
        pdef = ob.ProblemDefinition(problem.si)
        pdef.addStartState(_state(problem.space, self.start))
        pdef.setGoal(problem.goal)
        planner = _planner(self.settings.planner, problem.si)
        if self.settings.range > 0.0:
            planner.setRange(self.settings.range)
        planner.setProblemDefinition(pdef)
        planner.setup()
        self.iterations, self.cap = 0, budget
        status = planner.solve(ob.PlannerTerminationCondition(self._budget))
        self.used += min(self.iterations, budget)
        if status.getStatus() != ob.PlannerStatus.EXACT_SOLUTION:
            return self._not_found(pdef, planner, problem.si)
        path = pdef.getSolutionPath()
        simplify(problem.si, problem.goal, path, ROPE_RAD)
        return self._found(_waypoints(path))

    def _final(self, best: Found) -> Found:
        """The path kept, shortened once more with a finer rope."""
        if len(best.path) <= 2:
            return best
        problem = self._problem(self.goals, self.lo, self.hi, None)
        path = og.PathGeometric(problem.si, [_state(problem.space, q) for q in best.path])
        simplify(problem.si, problem.goal, path, FINAL_ROPE_RAD)
        found = self._found(_waypoints(path))
        return found if path_length(found.path) < path_length(best.path) else best

    def _found(self, waypoints: np.ndarray) -> Found:
        waypoints = shorten(waypoints, self.goals, self.floors.motion)
        end = int(np.argmin(np.abs(self.goals - waypoints[-1]).max(axis=1)))
        return Found(waypoints, end, self.used)

    def _not_found(
        self,
        pdef: ob.ProblemDefinition,
        planner: ob.Planner,
        si: ob.SpaceInformation,
    ) -> NotFound:
        data = ob.PlannerData(si)
        planner.getPlannerData(data)
        tags = [data.getVertex(i).getTag() for i in range(data.numVertices())]
        states = (tags.count(1), tags.count(2))
        closest = self.start
        if pdef.hasApproximateSolution():
            path = pdef.getSolutionPath()
            closest = _array(path.getState(path.getStateCount() - 1))
        gaps = np.linalg.norm(self.goals - closest, axis=1)
        k = int(np.argmin(gaps))
        return NotFound(self.used, states, closest, float(gaps[k]), k)


def _waypoints(path: og.PathGeometric) -> np.ndarray:
    return np.array([_array(path.getState(i)) for i in range(path.getStateCount())])


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
