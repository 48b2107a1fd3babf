"""The simulator's run-time fault door: ``sim/fault`` requests -> ``SimCore.add_fault``.

:func:`fault_from_request` turns a :class:`~schemas.simfault.SimFault` into one of the
fault values of :mod:`services.simulator.faults`, placed on the simulator's own clock
(``start_in_ms`` after ``now_ns``); :class:`FaultDesk` answers the queryable in the live
simulator, under the loop's lock. The arm has no such door: only the simulator opens it.
"""

from __future__ import annotations

from manus.errors import ConfigError
from schemas.simfault import SimFault, SimFaultKind, SimFaultReply
from services.simulator.faults import Fault, FrameFault, InjectedMessage, Silence, StuckJoint
from services.simulator.live import LiveSim


def fault_from_request(request: SimFault, now_ns: int) -> Fault | None:
    """The fault ``request`` asks for, starting ``start_in_ms`` after ``now_ns`` [ns]
    (None: ``clear``).

    Raises:
        ConfigError: the values are not a valid fault (names the field and limit).
    """
    kind = SimFaultKind(request.kind)
    start_ms = now_ns / 1e6 + request.start_in_ms
    duration = request.duration_ms or None
    if kind is SimFaultKind.CLEAR:
        return None
    if kind is SimFaultKind.SILENCE:
        return Silence(start_ms, duration)
    if kind in (SimFaultKind.WARNING, SimFaultKind.ERROR):
        return InjectedMessage(kind.value, request.code, start_ms, request.duration_ms or 60.0)
    if kind is SimFaultKind.STUCK:
        return StuckJoint(request.joint, start_ms, duration)
    return FrameFault(
        kind.value,
        rate=request.rate,
        start_ms=start_ms,
        duration_ms=duration,
        count=request.count or None,
        ids=tuple(request.ids),
        delay_ms=request.delay_ms,
        corrupt=request.corrupt,
    )


class FaultDesk:
    """Answers ``sim/fault`` for a running :class:`LiveSim`.

    Attributes:
        accepted: requests that switched a fault on or cleared them.
        refused: requests with invalid values.
    """

    def __init__(self, live: LiveSim) -> None:
        self.live = live
        self.accepted = 0
        self.refused = 0

    def __call__(self, request: SimFault) -> SimFaultReply:
        """Switch the requested fault on now (under the simulator loop's lock)."""
        with self.live.lock:
            now = self.live.sim_time_ns()
            try:
                fault = fault_from_request(request, now)
            except ConfigError as exc:
                self.refused += 1
                return SimFaultReply(ok=False, sim_time_ns=now, start_ns=now, message=str(exc))
            if fault is None:
                self.live.core.clear_faults()
                self.accepted += 1
                return SimFaultReply(ok=True, sim_time_ns=now, start_ns=now, message="cleared")
            self.live.core.add_fault(fault)
        self.accepted += 1
        start = now + round(request.start_in_ms * 1e6)
        return SimFaultReply(ok=True, sim_time_ns=now, start_ns=start, message=repr(fault))
