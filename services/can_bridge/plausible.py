"""Position fields that jump further than the arm can move are a fault of their cycle.

The arm's fastest motor moves 3 units (0.3 deg) per 20 ms tick: nine per cycle, so a field
that changes by more than ``max_field_step`` per cycle since the last accepted one is a
garbled frame (or a bit error the CAN checksum missed). Two consecutive cycles that agree
with each other re-base the reference (a genuine jump: the arm moved while the bridge did
not see it, e.g. after a restart). Not checked while the positions are not valid yet
(start-up): the reference starts afresh when they become valid.
"""

from __future__ import annotations


class FieldCheck:
    """The plausibility of the position fields from cycle to cycle (module docstring).

    Args:
        step: largest plausible change of a field per cycle [field units].
    """

    def __init__(self, step: int) -> None:
        self.step = step
        self._ref: tuple[tuple[int, ...], int] | None = None  # accepted fields, cycle index
        self._rejected: tuple[tuple[int, ...], int] | None = None

    def reset(self) -> None:
        """Forget the reference (the positions are not valid)."""
        self._ref, self._rejected = None, None

    def accept(self, fields: tuple[int, ...], index: int) -> bool:
        """The fields of cycle ``index`` are plausible (the reference moves to them)."""
        ref, rejected = self._ref, self._rejected
        if ref is None or _near(fields, ref[0], self.step * (index - ref[1])):
            self._ref, self._rejected = (fields, index), None
            return True
        if rejected is not None and _near(fields, rejected[0], self.step * (index - rejected[1])):
            self._ref, self._rejected = (fields, index), None
            return True
        self._rejected = (fields, index)
        return False


def _near(a: tuple[int, ...], b: tuple[int, ...], limit: int) -> bool:
    return all(abs(x - y) <= limit for x, y in zip(a, b, strict=True))
