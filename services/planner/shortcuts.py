"""Shortening a path the search found (:mod:`.search`): OMPL's simplifier, then two
passes of our own.

1. **OMPL** (:func:`simplify`): partial shortcuts (one joint at a time between random
   points of the path), vertex reduction and collapsing close vertices, for at most
   :data:`ROUNDS` rounds; then a rope shortcut (RRT-Rope: the path cut every ``rope`` rad,
   each cut connected straight to the farthest later one it sees; deterministic).
2. **The farthest waypoint each one sees** (:func:`greedy_shortcut`).
3. **The goal state that makes the path shortest** (:func:`nearer_goal`): the search
   reaches the goal state it happens to connect to first.

Every straight motion kept is one the floors (:class:`~services.planner.floors.Floors`)
proved clear.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from ompl import base as ob
from ompl import geometric as og

ROUNDS = 2
"""Most rounds of OMPL's partial shortcuts (fewer when a round changes nothing)."""

ROPE_RAD = 1.0
"""Spacing of the cuts of the rope shortcut of each path found [rad]."""

FINAL_ROPE_RAD = 0.5
"""Spacing of the cuts of the rope shortcut of the path kept [rad] (finer: its cost
grows with the square of the cuts, paid once)."""


def simplify(si: ob.SpaceInformation, goal: ob.Goal, path: og.PathGeometric, rope: float) -> None:
    """Shorten ``path`` in place with OMPL's simplifier (see the module docstring; ``rope``
    [rad]: the rope shortcut's spacing, 0: none)."""
    simplifier = og.PathSimplifier(si, goal)
    for _ in range(ROUNDS):
        changed = simplifier.partialShortcutPath(path)
        changed = simplifier.reduceVertices(path) or changed
        changed = simplifier.collapseCloseVertices(path) or changed
        if not changed:
            break
    if rope > 0.0:
        simplifier.ropeShortcutPath(path, rope)
        simplifier.reduceVertices(path)


def shorten(
    path: np.ndarray, goals: np.ndarray, clear: Callable[[np.ndarray, np.ndarray], bool]
) -> np.ndarray:
    """Our two passes: :func:`greedy_shortcut`, then :func:`nearer_goal`."""
    return nearer_goal(greedy_shortcut(path, clear), goals, clear)


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
    the rest of it."""
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


def path_length(path: np.ndarray) -> float:
    """Joint-space length of a path of waypoints [rad] (Euclidean per step)."""
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())
