"""Sorting the arm's frames into cycles by their arrival times (docs/architecture.md, Time).

Within each 60 ms cycle the arm sends 0x350, 0x360 and the 0x37F sync 20 ms apart. The
assembler anchors on the last sync it accepted and gives every later frame a 20 ms slot:
slot m after the anchor (m >= 1) holds 0x350 when m % 3 == 1, 0x360 when m % 3 == 2 and
the sync when m % 3 == 0, and belongs to cycle ``anchor + ceil(m / 3)``. A frame is *in
its slot* when its id matches the slot and it arrived within ``tolerance`` of the slot's
time. Anything else is a fault of the cycle the frame arrived in: a frame off its slot
(delayed, out of order), a second frame in a filled slot (duplicate), a frame with the
wrong length (garbled). Slots still empty when their cycle closes are counted dropped.

The anchor moves to every sync that is in its slot (so clock drift never accumulates),
and to an off-slot sync when the sync before it was off-slot too and one cycle earlier
(the arm's phase has changed, for example after a silence or a restart).

A cycle is *clean* when it holds exactly its three frames, each in its slot, and nothing
else arrived during it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

from manus.protocol import Frame, FrameId

SLOT_NS = 20_000_000
"""Spacing of the arm's frames [ns]."""
CYCLE_NS = 3 * SLOT_NS
"""The arm's cycle [ns]."""

Kind = Literal["status", "position", "sync", "garbled", "unknown"]

_SLOT_OF = {FrameId.STATUS: 1, FrameId.POSITION: 2, FrameId.SYNC: 0}
_ID_OF_SLOT = {slot: int(fid) for fid, slot in _SLOT_OF.items()}


def classify(frame: Frame) -> Kind:
    """What an arm frame is: one of the three cycle frames, garbled, or an unknown id."""
    if frame.id in (FrameId.STATUS, FrameId.POSITION):
        ok = not frame.remote and frame.dlc == 8 and len(frame.data) == 8
        return ("status" if frame.id == FrameId.STATUS else "position") if ok else "garbled"
    if frame.id == FrameId.SYNC:
        return "sync" if frame.remote and frame.dlc == 0 else "garbled"
    return "unknown"


@dataclass
class Cycle:
    """The frames of one cycle as they arrived.

    Attributes:
        index: cycle number, counted from the first anchor.
        status: the 0x350 in its slot, if any.
        position: the 0x360 in its slot, if any.
        sync: the 0x37F in its slot, if any.
        faults: what went wrong in this cycle, in words (empty: nothing so far).
        touched: slots (by frame id) that a garbled frame of that id occupied.
        missing: frames counted dropped when the cycle closed.
    """

    index: int
    status: Frame | None = None
    position: Frame | None = None
    sync: Frame | None = None
    faults: list[str] = field(default_factory=list)
    touched: set[int] = field(default_factory=set)
    missing: int = 0

    @property
    def clean(self) -> bool:
        """All three frames in their slots and nothing else."""
        return (
            self.status is not None
            and self.position is not None
            and self.sync is not None
            and not self.faults
        )

    def _count_missing(self) -> int:
        slots = {FrameId.STATUS: self.status, FrameId.POSITION: self.position}
        slots[FrameId.SYNC] = self.sync
        gone = [f"0x{fid:03X}" for fid, f in slots.items() if f is None and fid not in self.touched]
        if gone:
            self.faults.append(f"{' and '.join(gone)} missing")
        return len(gone)


@dataclass(frozen=True)
class Placement:
    """Where one frame went.

    Attributes:
        kind: what the frame is (:func:`classify`).
        cycle: the cycle it was put in (None for unknown ids).
        in_slot: it arrived in its own slot (and filled it).
        duplicate: its slot was already filled.
        late: it belongs to a cycle that has already closed.
        closed: cycles closed by this frame (the previous one when a sync ended it or a
            later frame skipped its end; whole cycles skipped count 3 missing frames each
            in ``skipped_frames``).
        skipped_frames: frames of whole cycles that passed without a single frame.
    """

    kind: Kind
    cycle: Cycle | None
    in_slot: bool = False
    duplicate: bool = False
    late: bool = False
    closed: tuple[Cycle, ...] = ()
    skipped_frames: int = 0


class CycleAssembler:
    """Sorts frames into cycles (see the module docstring).

    Args:
        tolerance_ns: largest deviation from a slot's time [ns] (< 10 ms).
    """

    def __init__(self, tolerance_ns: int) -> None:
        self.tolerance_ns = tolerance_ns
        self.anchor_ns: int | None = None
        """Arrival time of the sync the slots count from [ns]; None before the first."""
        self.anchor_index = 0
        self.current = Cycle(0)
        """The cycle being assembled."""
        self.last_sync_period_ns: int | None = None
        """Arrival spacing of the last two in-slot syncs of consecutive cycles [ns]."""
        self._candidate_ns: int | None = None

    def place(self, frame: Frame) -> Placement:
        """Put ``frame`` (stamped with its arrival time) into its cycle."""
        kind = classify(frame)
        if kind == "unknown":
            return Placement(kind, None)
        if self.anchor_ns is None:
            return self._place_unanchored(frame, kind)
        t = frame.t_ns - self.anchor_ns
        m = round(t / SLOT_NS)
        dev = t - m * SLOT_NS
        in_time = abs(dev) <= self.tolerance_ns
        in_slot = m >= 1 and in_time and m % 3 == _SLOT_OF[FrameId(frame.id)]
        if in_slot:
            index = self.anchor_index + (m + 2) // 3
        else:
            index = self.anchor_index + max(1, math.ceil((t - self.tolerance_ns) / CYCLE_NS))
        cur = self.current
        if index < cur.index:
            cur.faults.append(f"0x{frame.id:03X} of an earlier cycle arrived late")
            return Placement(kind, cur, late=True)
        closed: list[Cycle] = []
        skipped = 0
        if index > cur.index:
            cur.missing = cur._count_missing()
            closed.append(cur)
            skipped = 3 * (index - cur.index - 1)
            cur = self.current = Cycle(index)
            if skipped:
                cur.faults.append(f"{skipped} frames of whole cycles missing")
        duplicate = False
        fid = FrameId(frame.id)
        if kind == "garbled":
            cur.faults.append(f"0x{frame.id:03X} garbled (DLC {frame.dlc}, remote {frame.remote})")
            cur.touched.add(fid)
        elif not in_slot:
            duplicate = kind == "sync" and m == 0 and in_time
            if duplicate:
                what = "duplicated"
            elif in_time and m >= 1:
                what = f"out of order (in the slot of 0x{_ID_OF_SLOT[m % 3]:03X})"
            else:
                what = f"off its slot by {dev / 1e6:+.1f} ms"
            cur.faults.append(f"0x{frame.id:03X} {what}")
        elif self._slot(cur, fid) is not None:
            duplicate = True
            cur.faults.append(f"0x{frame.id:03X} duplicated")
        else:
            self._fill(cur, fid, frame)
        if fid == FrameId.SYNC and not duplicate:
            closed += self._sync_seen(frame, in_slot)
        return Placement(
            kind,
            cur,
            in_slot=in_slot and not duplicate and kind != "garbled",
            duplicate=duplicate,
            closed=tuple(closed),
            skipped_frames=skipped,
        )

    def _place_unanchored(self, frame: Frame, kind: Kind) -> Placement:
        cur = self.current
        if not cur.faults:
            cur.faults.append("not yet in step with the arm's cycle")
        fid = FrameId(frame.id)
        duplicate = False
        if kind == "garbled":
            cur.touched.add(fid)
        elif self._slot(cur, fid) is not None:
            duplicate = True
        else:
            self._fill(cur, fid, frame)
        closed: tuple[Cycle, ...] = ()
        if fid == FrameId.SYNC:
            closed = tuple(self._anchor(frame.t_ns, cur.index))
        return Placement(kind, cur, duplicate=duplicate, closed=closed)

    def _sync_seen(self, frame: Frame, in_slot: bool) -> list[Cycle]:
        t = frame.t_ns
        if in_slot:
            prev = self.anchor_ns
            cur = self.current
            if prev is not None and cur.index == self.anchor_index + 1:
                self.last_sync_period_ns = t - prev
            return self._anchor(t, cur.index)
        candidate, self._candidate_ns = self._candidate_ns, t
        if candidate is not None and abs(t - candidate - CYCLE_NS) <= self.tolerance_ns:
            return self._anchor(t, self.current.index)
        return []

    def _anchor(self, t: int, index: int) -> list[Cycle]:
        cur = self.current
        cur.missing = cur._count_missing()
        self.anchor_ns, self.anchor_index = t, index
        self._candidate_ns = None
        self.current = Cycle(index + 1)
        return [cur]

    @staticmethod
    def _slot(cycle: Cycle, fid: FrameId) -> Frame | None:
        if fid == FrameId.STATUS:
            return cycle.status
        if fid == FrameId.POSITION:
            return cycle.position
        return cycle.sync

    @staticmethod
    def _fill(cycle: Cycle, fid: FrameId, frame: Frame) -> None:
        if fid == FrameId.STATUS:
            cycle.status = frame
        elif fid == FrameId.POSITION:
            cycle.position = frame
        else:
            cycle.sync = frame
