"""Conservative advancement from one configuration: the controller's guard proves most
cycles without a distance.

At an *anchor* configuration each body has a margin (a lower bound: the fast check's,
or Coal's exact one) and each joint a reach to it (the farthest any point of the body is
from the joint's axis). Anywhere in the joint-space box from the anchor to a set of
configurations, a point of a body has moved at most ``sum_j |dq_j| r_j``, with ``r_j``
its largest distance from joint ``j``'s axis on the way; only the joints beyond ``j``
change that distance, so ``r_j <= reach_j + sum_{k>j} |dq_k| r_k``
(:func:`manus.motion_kernels.travel`). While that stays under every body's margin,
nothing can be violated (:func:`manus.sweep.sweep` bounds the same way). Compiled: a
check costs about a microsecond.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from manus import motion_kernels
from manus.validity import ValidityChecker


class Advancement:
    """The anchor and its proofs.

    Args:
        checker: the fast check (its bodies, in its order).
    """

    def __init__(self, checker: ValidityChecker) -> None:
        self.checker = checker
        bodies = len(checker.bodies)
        self._origin = np.zeros(6)
        self._free = np.full(bodies, -math.inf)
        self._reach = np.zeros((6, bodies))
        self.margin = -math.inf
        """The tightest margin at the anchor [m] (-inf: no anchor)."""

    def anchor_fast(self, q: np.ndarray) -> float:
        """Anchor at ``q`` [rad] with the fast check's margins (lower bounds: what they
        prove holds); returns the tightest [m]."""
        c = self.checker
        self._origin[:] = q
        self.margin = c.anchor_into(self._origin, self._free, self._reach)
        return self.margin

    def anchor(self, q: np.ndarray, free: np.ndarray, reach: np.ndarray, margin: float) -> None:
        """Anchor at ``q`` [rad] with known margins ``free`` (B,) [m] (inf: nothing to keep
        clear of), reaches ``reach`` (6, B) [m] and tightest ``margin`` [m] (Coal's)."""
        self._origin[:] = q
        self._free[:] = free
        self._reach[:] = reach
        self.margin = margin

    @property
    def free(self) -> np.ndarray:
        """Each body's margin at the anchor [m], shape (B,) (read only: a view)."""
        view = self._free.view()
        view.flags.writeable = False
        return view

    def forget(self) -> None:
        """No anchor: nothing is proven until the next one (a wider gripper, say)."""
        self._free[:] = -math.inf
        self.margin = -math.inf

    def shrink(self, by: float) -> None:
        """Every margin of the anchor less ``by`` [m] (something it keeps clear of moved
        by at most that much): what it proves stays conservative without a new distance."""
        self._free -= by
        self.margin -= by

    def proven(self, *qs: Sequence[float] | np.ndarray) -> bool:
        """Whether the box from the anchor to ``qs`` [rad] (each 6 values) keeps every
        body within its margin (see the module docstring)."""
        Q = np.array(qs, dtype=np.float64)
        return bool(motion_kernels.proven(self._origin, self._free, self._reach, Q))

    def proven_ahead(
        self,
        q: Sequence[float],
        first: Sequence[float] | np.ndarray,
        then: Sequence[float] | np.ndarray,
        to_q: np.ndarray,
        first_s: float,
        then_s: float,
    ) -> bool:
        """:meth:`proven` for ``q`` [rad], ``q1 = q + to_q @ first * first_s`` and
        ``q1 + to_q @ then * then_s`` (rates held for ``first_s`` and ``then_s`` [s];
        ``to_q`` (6, 6) maps them to joint rates [rad/s per unit]), in one call."""
        return bool(
            motion_kernels.proven_ahead(
                self._origin,
                self._free,
                self._reach,
                np.asarray(q, dtype=np.float64),
                np.asarray(first, dtype=np.float64),
                np.asarray(then, dtype=np.float64),
                to_q,
                first_s,
                then_s,
            )
        )
