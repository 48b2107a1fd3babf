"""What a goal plan keeps: the padding policy of the search, over the scene and the
arm's own work area.

- Away from its ends, a configuration keeps :attr:`Floors.padding` beyond every
  clearance (tracking errors and the final sweep's resolution eat into it) and
  :data:`AREA_PADDING_M` inside the arm's work area (:mod:`.work_area`).
- The start and the goal states need only their clearances and the work area: a goal
  may lie close to something (a grasp), and a start may lie anywhere the arm was left.
- A motion between two configurations keeps, all along, the smaller of the padding and
  what its two ends keep, less :data:`SLACK_M` (it could never leave a configuration
  exactly at its floor otherwise); an end outside the work area (the arm was left
  there) may only move out of it no deeper.

The start and the goal states are judged by the ``exact`` check (they may lie closer to
something than the fast check's bounds can prove), everything else by the ``fast`` one;
a motion from or to one of them that the fast check cannot even begin (its bound there
below the floor) is proven by the exact one (at most :data:`EXACT_MOTIONS` per search).
"""

from __future__ import annotations

import numpy as np

from services.planner.validity import Validity
from services.planner.work_area import WorkArea

SLACK_M = 0.001
"""How far below the smaller of its two ends' margins a motion may dip [m]."""

AREA_PADDING_M = 0.003
"""Margin kept inside the arm's work area away from the ends [m]."""

EXACT_MOTIONS = 24
"""Most motions from or to an end a search proves with the exact check (the rest of its
motions are the fast check's)."""


class Floors:
    """Which configurations are valid and what each motion keeps (see the module
    docstring).

    Args:
        fast: the fast, conservative check (the search).
        exact: the exact check (the start and the goal states).
        work: the arm's work area (None: not checked, as without a scene).
        padding: margin kept beyond the clearances away from the ends [m].
        ends: the start and the goal states [rad], each shape (6,).
    """

    def __init__(
        self,
        fast: Validity,
        exact: Validity,
        work: WorkArea | None,
        padding: float,
        ends: list[np.ndarray],
    ) -> None:
        self.fast, self.exact, self.work = fast, exact, work
        self.padding = padding
        self._ends = {np.asarray(q, dtype=float).tobytes() for q in ends}
        self._known: dict[bytes, tuple[float, float, bool]] = {}
        self.exact_left = EXACT_MOTIONS
        """Exact motion checks this search may still make."""

    def _margin(self, q: np.ndarray) -> tuple[float, float, bool]:
        """The smallest clearance margin at ``q`` [m], the work-area margin [m] (the
        elbow's counted as a length along the forearm), and whether ``q`` is an end (each
        configuration computed once: a search asks its tree's again and again)."""
        key = q.tobytes()
        found = self._known.get(key)
        if found is not None:
            return found
        end = key in self._ends
        # Away from the ends a margin above the padding counts as the padding: neither
        # the state's validity nor a motion's floor changes (cheaper).
        if end:
            margin = self.exact.margins(q).tightest
        else:
            margin = self.fast.margins(q, self.padding).tightest
        area = np.inf
        if self.work is not None:
            area = self.work.tightest(q)
        found = self._known[key] = (margin, area, end)
        return found

    def state(self, q: np.ndarray) -> bool:
        """Whether ``q`` [rad] may be on a path."""
        margin, area, end = self._margin(q)
        if end:
            return margin >= 0.0
        return margin >= self.padding and area >= AREA_PADDING_M

    def motion(self, qa: np.ndarray, qb: np.ndarray) -> bool:
        """Whether the straight joint motion ``qa`` -> ``qb`` [rad] keeps its floors."""
        (ma, aa, end_a), (mb, ab, end_b) = self._margin(qa), self._margin(qb)
        if not (self._ok(ma, aa, end_a) and self._ok(mb, ab, end_b)):
            return False
        if self.work is not None:
            area_floor = min(aa, ab, AREA_PADDING_M) - SLACK_M
            if not self.work.motion(qa, qb, area_floor):
                return False
        floor = max(min(ma, mb, self.padding) - SLACK_M, 0.0)
        if self.fast.motion(qa, qb, floor):
            return True
        # An end the fast bound cannot even leave: the exact check (a few of them per
        # search: each costs milliseconds).
        if self.exact_left > 0 and (
            (end_a and self.fast.margins(qa, floor).tightest < floor)
            or (end_b and self.fast.margins(qb, floor).tightest < floor)
        ):
            self.exact_left -= 1
            return self.exact.motion(qa, qb, floor)
        return False

    def _ok(self, margin: float, area: float, end: bool) -> bool:
        if end:
            return margin >= 0.0
        return margin >= self.padding and area >= AREA_PADDING_M
