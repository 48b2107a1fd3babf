"""Run-time fault injection into a running simulator (``sim/fault``): soaks and tests.

A real arm has no such door; the simulator opens it so that a chaos soak
(``manus bench chaos``) can make the arm's side misbehave while the whole stack runs:
the frame faults, silences, warning or error codes and stuck joints of
``services/simulator/faults.py``, each switched on ``start_in_ms`` after the request
arrives (simulator time), or every fault switched off (``clear``).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum

from schemas.base import Message, field


class SimFaultKind(StrEnum):
    """What a :class:`SimFault` switches on (or off)."""

    DROP = "drop"
    """drop the arm's frames"""
    DUPLICATE = "duplicate"
    """send the arm's frames twice"""
    DELAY = "delay"
    """send the arm's frames ``delay_ms`` late"""
    CORRUPT = "corrupt"
    """flip one data bit (``corrupt="bits"``) or send a wrong length (``"dlc"``)"""
    SILENCE = "silence"
    """the arm sends nothing"""
    WARNING = "warning"
    """the arm reports warning ``code`` for ``duration_ms``"""
    ERROR = "error"
    """the arm reports error ``code``, latched until a 0x370, and holds meanwhile"""
    STUCK = "stuck"
    """motor ``joint`` stops moving"""
    CLEAR = "clear"
    """every fault off (a latched error stays until a 0x370)"""


@dataclass(frozen=True)
class SimFault(Message):
    """Switch one fault on in the running simulator (fields unused by a kind are ignored)."""

    TYPE_NAME = "manus/SimFault/1"

    kind: str = field("what to switch on", choices=SimFaultKind)
    start_in_ms: float = field(
        "from when, after the request arrives", unit="ms", default=0.0, minimum=0.0
    )
    duration_ms: float = field(
        "how long it stays on (0: for ever, or until `count` hits)",
        unit="ms",
        default=0.0,
        minimum=0.0,
    )
    rate: float = field(
        "frame faults: probability that a frame is hit", default=1.0, minimum=0.0, maximum=1.0
    )
    count: int = field("frame faults: off after this many hits (0: no limit)", default=0, minimum=0)
    ids: list[int] = field(
        "frame faults: only frames with these CAN ids (empty: every frame)",
        default_factory=list,
    )
    delay_ms: float = field("delay: extra latency", unit="ms", default=30.0, minimum=0.0)
    corrupt: str = field("corrupt: bits or dlc", default="bits", choices=("bits", "dlc"))
    code: int = field("warning/error: message code", default=0, minimum=0, maximum=255)
    joint: int = field("stuck: motor 1..6", default=1, minimum=1, maximum=6)
    source: str = field("who asks", default="")


@dataclass(frozen=True)
class SimFaultReply(Message):
    """The simulator's answer to a :class:`SimFault`."""

    TYPE_NAME = "manus/SimFaultReply/1"

    ok: bool = field("switched on (or cleared)")
    sim_time_ns: int = field("the simulator's clock when the request arrived", unit="ns")
    start_ns: int = field("when the fault turns on, simulator time", unit="ns")
    message: str = field("what was done, or why it was refused")
