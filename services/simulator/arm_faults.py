"""Faults inside the arm, on a schedule: injected warnings and errors, stuck joints.

(Faults on the frames the arm sends are :class:`services.simulator.faults.FrameFaulter`.)
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from services.simulator.config import MS
from services.simulator.faults import InjectedMessage, StuckJoint


@dataclass
class ArmFaults:
    """The scheduled internal faults of one run (times in simulator ns)."""

    _errors: list[InjectedMessage] = field(default_factory=list)
    _warnings: list[InjectedMessage] = field(default_factory=list)
    _stuck: list[StuckJoint] = field(default_factory=list)

    def add(self, fault: InjectedMessage | StuckJoint) -> None:
        """Schedule one more fault."""
        if isinstance(fault, StuckJoint):
            self._stuck.append(fault)
        elif fault.msg_class == "error":
            self._errors.append(fault)
        else:
            self._warnings.append(fault)

    def clear(self) -> None:
        """Forget every scheduled fault."""
        self._errors.clear()
        self._warnings.clear()
        self._stuck.clear()

    def errors_due(self, t_ns: int) -> list[int]:
        """Codes of the errors that occur by ``t_ns`` (each returned once)."""
        due = [m for m in self._errors if t_ns >= round(m.at_ms * MS)]
        for m in due:
            self._errors.remove(m)
        return [m.code for m in due]

    def warnings_at(self, t_ns: int) -> set[int]:
        """Codes of the injected warnings holding at ``t_ns``."""
        held = set()
        for m in self._warnings:
            start = round(m.at_ms * MS)
            if start <= t_ns < start + round(m.duration_ms * MS):
                held.add(m.code)
        return held

    def stuck_at(self, t_ns: int) -> np.ndarray:
        """Which motors are stuck at ``t_ns``, shape (6,) of bool."""
        stuck = np.zeros(6, dtype=bool)
        for s in self._stuck:
            if s.active(t_ns):
                stuck[s.joint - 1] = True
        return stuck
