"""What the simulator counts: protocol events and injected faults, for tests and logs."""

from __future__ import annotations

from dataclasses import asdict, dataclass


@dataclass
class SimCounters:
    """Running counts since power-up (all plain event counts).

    Attributes:
        frames_sent: frames handed to the bus (after fault injection).
        replies_latched: PC replies accepted in a reply window.
        extra_replies: replies after the first one in the same window (ignored).
        outside_window: PC frames received outside a reply window (ignored).
        ack_frames: DLC-0 frames with id 0x350/0x360 from the PC (accepted, ignored).
        bad_frames: PC frames with a known id but the wrong DLC, or remote frames (ignored).
        unknown_frames: PC frames with an id the arm does not know (ignored).
        not_ready: move/fold replies before "absolute angles measured" (ignored).
        ignored_in_error: move/fold replies while an error is latched (ignored).
        clamped: replies with an increment outside its range (clamped, warning 7).
        dropped: outgoing frames dropped by a fault.
        duplicated: outgoing frames sent twice by a fault.
        delayed: outgoing frames sent late by a fault.
        corrupted: outgoing frames with flipped bits or a wrong DLC.
        silenced: outgoing frames suppressed by a silence fault.
    """

    frames_sent: int = 0
    replies_latched: int = 0
    extra_replies: int = 0
    outside_window: int = 0
    ack_frames: int = 0
    bad_frames: int = 0
    unknown_frames: int = 0
    not_ready: int = 0
    ignored_in_error: int = 0
    clamped: int = 0
    dropped: int = 0
    duplicated: int = 0
    delayed: int = 0
    corrupted: int = 0
    silenced: int = 0

    def as_dict(self) -> dict[str, int]:
        """The counts by name."""
        return asdict(self)
