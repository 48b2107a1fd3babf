"""The planner's refusal: a :class:`schemas.planning.PlanError` carried as an exception."""

from __future__ import annotations

from manus.errors import ManusError
from schemas.planning import PlanError


class PlanningError(ManusError):
    """A path cannot be planned; :attr:`error` says why and where.

    Attributes:
        error: the structured error sent back to the caller.
    """

    def __init__(self, error: PlanError) -> None:
        super().__init__(error.message)
        self.error = error


def refuse(
    reason: str,
    message: str,
    *,
    via_point: int = -1,
    line: int = 0,
    joint: int = 0,
    value: float | None = None,
    limit: float | None = None,
) -> PlanningError:
    """A :class:`PlanningError` (to raise) with the fields of :class:`PlanError`."""
    return PlanningError(
        PlanError(
            reason=reason,
            message=message,
            via_point=via_point,
            line=line,
            joint=joint,
            value=value,
            limit=limit,
        )
    )


def via_label(source: str, index: int, line: int) -> str:
    """``"square.txt line 5 (via point 3)"``: how messages name a via point."""
    where = f"{source} " if source else ""
    return f"{where}line {line} (via point {index})" if line else f"{where}via point {index}"
