"""When each replayed message goes out: the replay's clock, with rosbag2's player controls.

:class:`Playback` is deterministic (the caller passes the time, ``now`` [s], from any
monotonic clock): over the offsets of the scheduled messages it keeps the position, the
state (playing, paused, finished), the rate, the selection (``start_s`` .. ``until_s``) and
the loop count, and says when the next message is due. Pause, resume, step (one message
while paused), seek and rate changes take effect at once; a rate change keeps the current
position (the recorded time between messages is scaled from there on); a seek or resume
plays the next message at once and the following ones at the recorded pace.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Sequence

from schemas.playback import PlaybackControl, PlaybackStatus
from services.recorder.errors import RecordingError


class Playback:
    """The replay's clock (see the module docstring).

    Args:
        offsets: each scheduled message's offset from the first [s], non-decreasing.
        rate: time scale (2: twice as fast); None: as fast as possible.
        start_s: play from this offset [s].
        until_s: stop after this offset [s] (None: the end).
        loops: passes over the selection (>= 1).
        paused: start paused (``resume`` or ``step`` to go).

    Raises:
        RecordingError: a rate <= 0, loops < 1, or an empty selection.
    """

    def __init__(
        self,
        offsets: Sequence[float],
        *,
        rate: float | None = 1.0,
        start_s: float = 0.0,
        until_s: float | None = None,
        loops: int = 1,
        paused: bool = False,
    ) -> None:
        self._check_rate(rate)
        if loops < 1:
            raise RecordingError(f"--loop {loops}: must be >= 1")
        self.offsets = list(offsets)
        self.first = bisect.bisect_left(self.offsets, start_s)
        end = len(self.offsets) if until_s is None else bisect.bisect_right(self.offsets, until_s)
        self.end = end
        if self.first >= self.end:
            raise RecordingError(
                f"nothing to replay between {start_s:g} s and "
                f"{'the end' if until_s is None else f'{until_s:g} s'} "
                f"(the selection spans 0 .. {self.offsets[-1] if self.offsets else 0:g} s)"
            )
        self.rate = rate
        self.loops = loops
        self.index = self.first
        self.loop = 1
        self.state = "paused" if paused else "playing"
        self.published = 0
        self._steps = 0
        self._anchor: tuple[float, float] | None = None  # (now, offset) that play together

    @staticmethod
    def _check_rate(rate: float | None) -> None:
        if rate is not None and not (rate > 0 and math.isfinite(rate)):
            raise RecordingError(f"replay rate {rate} must be > 0")

    def _virtual(self, now: float) -> float:
        """The recorded offset that plays at ``now`` (while playing)."""
        if self._anchor is None or self.rate is None:
            return self.offsets[min(self.index, len(self.offsets) - 1)]
        wall, offset = self._anchor
        return offset + (now - wall) * self.rate

    def due(self, now: float) -> float | None:
        """When the next message should go (``<= now``: at once); None when paused with no
        step pending, or finished."""
        if self.state == "finished":
            return None
        if self.state == "paused":
            return now if self._steps else None
        if self.rate is None:
            return now
        if self._anchor is None:
            self._anchor = (now, self.offsets[self.index])
        wall, offset = self._anchor
        return wall + (self.offsets[self.index] - offset) / self.rate

    def take(self, now: float) -> int:
        """The index of the message to publish now; moves on (next loop, or finished)."""
        i = self.index
        self.published += 1
        if self.state == "paused":
            self._steps -= 1
        self.index += 1
        if self.index >= self.end:
            if self.loop < self.loops:
                self.loop += 1
                self.index = self.first
                self._anchor = None
            else:
                self.state = "finished"
        return i

    def control(self, req: PlaybackControl, now: float) -> PlaybackStatus:
        """Carry out a control request; the status after it."""
        act = {
            "pause": self._pause,
            "resume": self._resume,
            "step": self._step,
            "seek": self._seek,
            "rate": self._rate,
        }.get(req.action)
        refusal = act(req.value, now) if act is not None else ""
        return self.status(not refusal, refusal)

    def _pause(self, value: float, now: float) -> str:
        if self.state == "playing":
            self.state = "paused"
            self._anchor = None
        return ""

    def _resume(self, value: float, now: float) -> str:
        if self.state == "paused":
            self.state = "playing"
            self._steps = 0
            self._anchor = None
        return ""

    def _step(self, value: float, now: float) -> str:
        if self.state != "paused":
            return f"step: only while paused (the replay is {self.state})"
        self._steps += 1
        return ""

    def _seek(self, value: float, now: float) -> str:
        first, last = self.offsets[self.first], self.offsets[self.end - 1]
        if not first <= value <= last:
            return f"seek {value:g} s: outside {first:g} .. {last:g} s"
        self.index = bisect.bisect_left(self.offsets, value, self.first, self.end)
        self._anchor = None
        if self.state == "finished":
            self.state = "paused"
        return ""

    def _rate(self, value: float, now: float) -> str:
        try:
            self._check_rate(value)
        except RecordingError as exc:
            return str(exc)
        if self.state == "playing" and self._anchor is not None:
            self._anchor = (now, self._virtual(now))
        self.rate = value
        return ""

    def status(self, ok: bool = True, message: str = "") -> PlaybackStatus:
        """Where the replay is."""
        position = self.offsets[min(self.index, self.end - 1)]
        return PlaybackStatus(
            ok=ok,
            state=self.state,
            position=position,
            duration=self.offsets[self.end - 1],
            rate=0.0 if self.rate is None else self.rate,
            published=self.published,
            loop=self.loop,
            message=message,
        )
