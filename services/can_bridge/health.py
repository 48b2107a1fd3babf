"""The bridge's timing health and fault counters, as published in ``BridgeState``."""

from __future__ import annotations

from dataclasses import dataclass

from manus.protocol import REPLY_WINDOW_S
from schemas.state import BridgeState

WINDOW_NS = round(REPLY_WINDOW_S * 1e9)
"""The arm's reply window after a sync [ns]."""


@dataclass
class Health:
    """Counters since start (units in the names; see :class:`schemas.state.BridgeState`)."""

    cycles: int = 0
    period_ms: float = 0.0
    jitter_ms: float = 0.0
    reply_latency_ms: float = 0.0
    reply_latency_max_ms: float = 0.0
    missed_windows: int = 0
    stale_commands: int = 0
    resyncs: int = 0
    dropped_frames: int = 0
    duplicate_frames: int = 0
    garbled_frames: int = 0
    buffered_syncs: int = 0
    bad_payloads: int = 0
    late_frames: int = 0
    replies: int = 0
    other_node_frames: int = 0
    preempted_replies: int = 0
    buffered_states: int = 0

    def period(self, period_ns: int) -> None:
        """A sync-to-sync period of consecutive cycles [ns]."""
        self.period_ms = period_ns / 1e6
        self.jitter_ms = max(self.jitter_ms, abs(self.period_ms - 60.0))

    def reply_sent(self, sync_rx_ns: int, sent_ns: int) -> None:
        """A reply to the sync received at ``sync_rx_ns`` left at ``sent_ns`` [ns]."""
        latency = sent_ns - sync_rx_ns
        self.reply_latency_ms = latency / 1e6
        self.reply_latency_max_ms = max(self.reply_latency_max_ms, self.reply_latency_ms)
        self.missed_windows += latency >= WINDOW_NS

    def state(
        self, *, stamp_ns: int, seq: int, phase: str, estop: bool, detail: str
    ) -> BridgeState:
        """The ``BridgeState`` message of these counters."""
        return BridgeState(
            stamp_ns=stamp_ns,
            seq=seq,
            phase=phase,
            estop=estop,
            cycles=self.cycles,
            period_ms=self.period_ms,
            jitter_ms=self.jitter_ms,
            reply_latency_ms=self.reply_latency_ms,
            reply_latency_max_ms=self.reply_latency_max_ms,
            missed_windows=self.missed_windows,
            stale_commands=self.stale_commands,
            resyncs=self.resyncs,
            dropped_frames=self.dropped_frames,
            duplicate_frames=self.duplicate_frames,
            garbled_frames=self.garbled_frames,
            buffered_syncs=self.buffered_syncs,
            bad_payloads=self.bad_payloads,
            detail=detail,
            late_frames=self.late_frames,
            other_node_frames=self.other_node_frames,
            preempted_replies=self.preempted_replies,
            buffered_states=self.buffered_states,
        )
