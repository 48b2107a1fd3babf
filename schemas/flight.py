"""Asking the flight recorder to keep what it holds (``manus record --ring``).

The flight recorder keeps the last seconds of every key in memory and writes them, with
the next few seconds, to a file when something goes wrong (an e-stop, an arm error, an
aborted goal, a failed task, a service that vanished) or when anyone asks on
``<prefix>/recorder/trigger`` (``schemas.endpoints.FLIGHT_TRIGGER``) with a
:class:`FlightTrigger`: an operator
who saw something odd, a test, a supervisor.
"""

from __future__ import annotations

from dataclasses import dataclass

from schemas.base import Message, field


@dataclass(frozen=True)
class FlightTrigger(Message):
    """Write the flight recorder's memory (and the next seconds) to a file now."""

    TYPE_NAME = "manus/FlightTrigger/1"

    stamp_ns: int = field("time it was sent", unit="ns")
    seq: int = field("sequence number of the sender", minimum=0)
    source: str = field("who asks (e.g. 'operator', 'supervisor')")
    reason: str = field("why, in words (goes into the file's name and metadata)", default="")
