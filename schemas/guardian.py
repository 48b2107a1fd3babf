"""What the CAN guardian reports (``manus guardian``, :mod:`services.guardian`).

The guardian itself never touches Zenoh; its reporter (a separate process fed through a
pipe) publishes one :class:`GuardianReport` on ``<prefix>/guardian/report`` for each
action (a 0x370 sent for an unanswered sync, a sync noticed too late, the bridge
answering again) and once a second with the running counts.
"""

from __future__ import annotations

from dataclasses import dataclass

from schemas.base import Message, field

GUARDIAN_ACTIONS = ("started", "stop_sent", "late", "bridge_back", "counts", "stopped")
"""Values of :attr:`GuardianReport.action`."""


@dataclass(frozen=True)
class GuardianReport(Message):
    """One action of the guardian, with its counts since start."""

    TYPE_NAME = "manus/GuardianReport/1"

    stamp_ns: int = field("wall clock when the reporter received it", unit="ns")
    seq: int = field("sequence number", minimum=0)
    action: str = field("what happened", choices=GUARDIAN_ACTIONS)
    sync_age_ms: float = field(
        "time from the sync concerned to the decision (0 for started, counts, stopped)",
        unit="ms",
        minimum=0.0,
    )
    syncs: int = field("syncs seen since start", minimum=0)
    answered: int = field("syncs answered by another node within the window", minimum=0)
    stops_sent: int = field("0x370 frames the guardian sent", minimum=0)
    late: int = field("unanswered syncs noticed after the window had closed", minimum=0)
    engaged: bool = field("the guardian is stopping the arm (the last sync went unanswered)")
    detail: str = field("the event in words", default="")
