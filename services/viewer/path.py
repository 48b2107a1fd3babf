"""The gripper's path as the viewer draws it: bounded, thinned, published in batches."""

from __future__ import annotations

from collections import deque


class GripperPath:
    """A bounded gripper path: a point only after a move of ``step`` [m].

    Args:
        most: most points kept (the oldest go first).
        step: a new point only this far from the last one [m].
        every: :meth:`add` says the path is due after this many new points.
    """

    def __init__(self, most: int, step: float, every: int) -> None:
        self.points: deque[tuple[float, float, float]] = deque(maxlen=most)
        self.step2 = step**2
        self.every = every
        self.pending = 0

    def add(self, xyz: tuple[float, float, float]) -> bool:
        """Append ``xyz`` if far enough from the last point; True when the path is due."""
        if self.points:
            last = self.points[-1]
            d2 = (xyz[0] - last[0]) ** 2 + (xyz[1] - last[1]) ** 2 + (xyz[2] - last[2]) ** 2
            if d2 < self.step2:
                return False
        self.points.append(xyz)
        self.pending += 1
        if self.pending >= self.every or len(self.points) == 2:
            self.pending = 0
            return True
        return False

    def clear(self) -> None:
        self.points.clear()
        self.pending = 0
