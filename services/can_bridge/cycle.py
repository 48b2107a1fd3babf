"""Sorting the arm's frames into cycles by their arrival times (docs/architecture.md, Time).

Within each 60 ms cycle the arm sends 0x350, 0x360 and the 0x37F sync 20 ms apart. The
assembler keeps an *anchor*, its estimate of when the last sync arrived without delay,
and gives every frame the cycle whose nominal time for that frame (anchor + 20, 40, 60 ms
+ 60 ms per cycle) it follows by at most one cycle, allowing ``tolerance`` early. So a
frame that is late but still in order (a busy sender or receiver) is accepted, while a
frame that arrives after a later frame of its cycle (delayed past it: out of order), a
second frame of a kind (duplicate), a frame with the wrong length (garbled), or a frame of
a cycle that has already ended is a fault of the cycle it arrived in. Frames still missing
when their cycle ends are counted dropped.

Arrival delays only ever add, so the anchor is the earliest of the last ``ANCHOR_SYNCS``
syncs carried forward by whole cycles: one late sync does not move it, an early one moves
it at once, and a lasting shift or a slow clock drift is followed within ``ANCHOR_SYNCS``
cycles. Two syncs a cycle apart that both land in cycles already ended re-anchor (the
arm's phase moved earlier by more than ``tolerance``, e.g. after a restart).

A cycle is *clean* when it holds exactly its three frames, in order, and nothing else
arrived during it.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import Literal

from manus.protocol import Frame, FrameId

SLOT_NS = 20_000_000
"""Spacing of the arm's frames [ns]."""
CYCLE_NS = 3 * SLOT_NS
"""The arm's cycle [ns]."""
ANCHOR_SYNCS = 8
"""The anchor is the earliest of this many recent syncs, carried forward by cycles."""

Kind = Literal["status", "position", "sync", "garbled", "unknown"]

_SLOT_OF = {FrameId.STATUS: 1, FrameId.POSITION: 2, FrameId.SYNC: 3}


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
        accepted: it took its place in its cycle, in order (its first of a kind).
        duplicate: its slot was already filled.
        late: it arrived out of order: after a later frame of its cycle, or after its
            cycle had closed.
        closed: cycles closed by this frame (the previous one when a sync ended it or a
            later frame skipped its end; whole cycles skipped count 3 missing frames each
            in ``skipped_frames``).
        skipped_frames: frames of whole cycles that passed without a single frame.
    """

    kind: Kind
    cycle: Cycle | None
    accepted: bool = False
    duplicate: bool = False
    late: bool = False
    closed: tuple[Cycle, ...] = ()
    skipped_frames: int = 0


class CycleAssembler:
    """Sorts frames into cycles (see the module docstring).

    Args:
        tolerance_ns: how much earlier than its nominal time a frame may arrive [ns]
            (< 10 ms; frames may be up to one cycle minus this late).
    """

    def __init__(self, tolerance_ns: int) -> None:
        self.tolerance_ns = tolerance_ns
        self.anchor_ns: int | None = None
        """Estimated undelayed arrival of the last sync [ns] (see the module docstring);
        None before the first sync."""
        self.anchor_index = 0
        self.current = Cycle(0)
        """The cycle being assembled."""
        self.last_sync_period_ns: int | None = None
        """Arrival spacing of the last two in-order syncs of consecutive cycles [ns]."""
        self._candidate_ns: int | None = None
        self._last_closed: Cycle | None = None
        self._recent: deque[tuple[int, int]] = deque(maxlen=ANCHOR_SYNCS)

    def place(self, frame: Frame) -> Placement:
        """Put ``frame`` (stamped with its arrival time) into its cycle."""
        kind = classify(frame)
        if kind == "unknown":
            return Placement(kind, None)
        if self.anchor_ns is None:
            return self._place_unanchored(frame, kind)
        fid = FrameId(frame.id)
        slot = _SLOT_OF[fid]
        t = frame.t_ns - self.anchor_ns
        # Cycle n after the anchor holds this frame if it is at most `tolerance` early and
        # less than one cycle minus `tolerance` late.
        n = (t - slot * SLOT_NS + self.tolerance_ns) // CYCLE_NS + 1
        lateness_ms = (t - (3 * (n - 1) + slot) * SLOT_NS) / 1e6
        index = self.anchor_index + n
        cur = self.current
        if index < cur.index:
            return self._late(frame, kind, index, lateness_ms)
        closed: list[Cycle] = []
        skipped = 0
        if index > cur.index:
            cur.missing = cur._count_missing()
            closed.append(cur)
            skipped = 3 * (index - cur.index - 1)
            cur = self.current = Cycle(index)
            if skipped:
                cur.faults.append(f"{skipped} frames of whole cycles missing")
        filled = [f for f in (cur.status, cur.position) if f is not None]
        accepted = late = duplicate = False
        if kind == "garbled":
            cur.faults.append(f"0x{frame.id:03X} garbled (DLC {frame.dlc}, remote {frame.remote})")
            cur.touched.add(fid)
        elif self._slot(cur, fid) is not None:
            duplicate = True
            cur.faults.append(f"0x{frame.id:03X} duplicated")
        elif any(_SLOT_OF[FrameId(f.id)] > slot for f in filled):
            cur.faults.append(f"0x{frame.id:03X} out of order ({lateness_ms:+.1f} ms late)")
            cur.touched.add(fid)
            late = True
        else:
            accepted = True
            self._fill(cur, fid, frame)
        if fid == FrameId.SYNC and not duplicate:
            closed += self._close(frame.t_ns, index)
        return Placement(
            kind,
            cur,
            accepted=accepted,
            duplicate=duplicate,
            late=late,
            closed=tuple(closed),
            skipped_frames=skipped,
        )

    def _late(self, frame: Frame, kind: Kind, index: int, lateness_ms: float) -> Placement:
        """A frame of a cycle already closed: a duplicate of its frame, or out of order."""
        cur = self.current
        fid = FrameId(frame.id)
        last = self._last_closed
        original = self._slot(last, fid) if last is not None and last.index == index else None
        if original is not None and frame.t_ns - original.t_ns <= self.tolerance_ns:
            cur.faults.append(f"0x{frame.id:03X} duplicated")
            return Placement(kind, cur, duplicate=True)
        cur.faults.append(f"0x{frame.id:03X} of an earlier cycle ({lateness_ms:+.1f} ms late)")
        closed: tuple[Cycle, ...] = ()
        if fid == FrameId.SYNC:
            # The arm's phase may have moved earlier: two such syncs a cycle apart re-anchor.
            candidate, self._candidate_ns = self._candidate_ns, frame.t_ns
            if (
                candidate is not None
                and abs(frame.t_ns - candidate - CYCLE_NS) <= self.tolerance_ns
            ):
                self._recent.clear()
                self._recent.append((cur.index, frame.t_ns))
                closed = tuple(self._anchor(frame.t_ns, cur.index))
        return Placement(kind, cur, late=True, closed=closed)

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
            self._recent.append((cur.index, frame.t_ns))
            closed = tuple(self._anchor(frame.t_ns, cur.index))
        return Placement(kind, cur, duplicate=duplicate, closed=closed)

    def _close(self, t: int, index: int) -> list[Cycle]:
        """A sync arrived at ``t`` ends cycle ``index``.

        Arrival delays only ever add, so the anchor is the earliest of the last
        ``ANCHOR_SYNCS`` syncs, each carried forward by whole cycles: one late sync does
        not move it, an early one moves it at once, a lasting shift or a slow drift within
        ``ANCHOR_SYNCS`` cycles.
        """
        previous = self._recent[-1] if self._recent else None
        if previous is not None and previous[0] == index - 1:
            self.last_sync_period_ns = t - previous[1]
        self._recent.append((index, t))
        anchor = min(a + (index - i) * CYCLE_NS for i, a in self._recent)
        return self._anchor(anchor, index)

    def _anchor(self, t: int, index: int) -> list[Cycle]:
        cur = self.current
        cur.missing = cur._count_missing()
        self.anchor_ns, self.anchor_index = t, index
        self._candidate_ns = None
        self._last_closed = cur
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
