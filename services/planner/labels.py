"""What each knot of a trajectory being planned is, and how refusals name it.

Every stage after a planner's own (the checks along the curve, the speed limits, the
collision sweep) names a knot or the segment between two through :class:`KnotLabels`:
a via point of the request's path by its file, line and index there (``square.txt line 5
(via point 3)``, as the via-point file rules do), a planner's waypoint by its place in
the trajectory, the start of a resumed plan as the start. The same labels become the
trajectory's ``knot_kinds``, ``via_indices`` and ``via_lines``.
"""

from __future__ import annotations

from dataclasses import dataclass

from schemas.planning import KnotKind, Path
from services.planner.errors import via_label


@dataclass(frozen=True)
class KnotLabels:
    """The knots of one trajectory, each as what it is.

    Attributes:
        source: where the path came from (a file name; '' none), for messages.
        kinds: what each knot is, shape (n,).
        via_indices: each knot's via point's index in the request's path (-1: none).
        lines: each knot's via point's source line (0: none).
    """

    source: str
    kinds: tuple[KnotKind, ...]
    via_indices: tuple[int, ...]
    lines: tuple[int, ...]

    @classmethod
    def of_path(cls, path: Path) -> KnotLabels:
        """Knot i is via point i of ``path`` (via point 0, replaced by the start, is the
        start)."""
        n = len(path.via_points)
        return cls(
            source=path.source,
            kinds=(KnotKind.START, *(KnotKind.VIA_POINT,) * (n - 1)),
            via_indices=tuple(range(n)),
            lines=tuple(vp.line for vp in path.via_points),
        )

    def label(self, k: int, *, with_source: bool = True) -> str:
        """How messages name knot ``k``: ``"square.txt line 5 (via point 3)"``, ``"the
        start"``, ``"waypoint 2 (knot 4)"``, ``"the goal"``."""
        source = self.source if with_source else ""
        index = self.via_indices[k]
        if index >= 0:
            return via_label(source, index, self.lines[k])
        head = f"{source} " if source else ""
        if self.kinds[k] == KnotKind.START:
            return f"{head}the start"
        if self.kinds[k] == KnotKind.GOAL:
            return f"{head}the goal"
        waypoint = sum(kind == KnotKind.WAYPOINT for kind in self.kinds[:k]) + 1
        return f"{head}waypoint {waypoint} (knot {k})"

    def between(self, segment: int) -> str:
        """``"between <knot> and <next knot>"`` for a segment (its first knot's index)."""
        return f"between {self.label(segment)} and {self.label(segment + 1, with_source=False)}"
