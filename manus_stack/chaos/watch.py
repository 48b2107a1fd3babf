"""The soak's own eyes: one Zenoh node that keeps what the judge needs.

- every sample under the prefix, as (key, 8-byte hash of its payload, receive time
  [wall ns]): the reference the recordings are compared with (the soak's node is a
  subscriber like the recorder, on the same router, so a message the recorder should
  have and lacks is one the router delivered to us);
- each ``sim/truth`` (the simulator's clock and true joint angles) with its receive time,
  which also gives the offset from wall clock to simulator clock;
- the sequencer's task events and the bridge's states;
- every liveliness change (service, up, wall ns).
"""

from __future__ import annotations

import hashlib
import threading
import time
from dataclasses import dataclass, field

import zenoh

from manus.node import Node
from manus.session import ZenohSettings
from schemas import endpoints as ep
from schemas.sequencing import TaskEvent
from schemas.state import BridgeState, SimTruth


def digest(payload: bytes) -> bytes:
    """The 8-byte hash a message is matched by."""
    return hashlib.blake2b(payload, digest_size=8).digest()


@dataclass
class Seen:
    """What the node has received (append-only, guarded by ``lock``)."""

    lock: threading.Lock = field(default_factory=threading.Lock)
    samples: list[tuple[str, bytes, int]] = field(default_factory=list)
    truth: list[tuple[int, SimTruth]] = field(default_factory=list)
    events: list[TaskEvent] = field(default_factory=list)
    bridge: list[BridgeState] = field(default_factory=list)
    alive: list[tuple[str, bool, int]] = field(default_factory=list)


class Watcher:
    """Subscribes to everything under the prefix (see the module docstring).

    Args:
        settings: how to reach the stack's router.
    """

    def __init__(self, settings: ZenohSettings) -> None:
        self.seen = Seen()
        self.node = Node("chaos", settings, liveliness=False)
        keys = self.node.keys
        self._truth = keys(ep.SIM_TRUTH)
        self._events = keys(ep.EVENTS)
        self._bridge = keys(ep.BRIDGE_STATE)
        self._liveliness = keys.liveliness
        self.node.subscribe_raw(keys.all, self._on_sample)
        self.node.watch_liveliness(self._on_alive)

    def _on_sample(self, sample: zenoh.Sample, rx_ns: int) -> None:
        if sample.kind != zenoh.SampleKind.PUT:
            return
        key = str(sample.key_expr)
        payload = sample.payload.to_bytes()
        s = self.seen
        decoded: object = None
        try:
            if key == self._truth:
                decoded = SimTruth.decode(payload)
            elif key == self._events:
                decoded = TaskEvent.decode(payload)
            elif key == self._bridge:
                decoded = BridgeState.decode(payload)
        except Exception:  # a garbage payload is the stack's business, not the soak's
            decoded = None
        with s.lock:
            s.samples.append((key, digest(payload), rx_ns))
            if isinstance(decoded, SimTruth):
                s.truth.append((rx_ns, decoded))
            elif isinstance(decoded, TaskEvent):
                s.events.append(decoded)
            elif isinstance(decoded, BridgeState):
                s.bridge.append(decoded)

    def _on_alive(self, service: str, up: bool) -> None:
        with self.seen.lock:
            self.seen.alive.append((service, up, time.time_ns()))

    def sim_offset_ns(self) -> int:
        """Wall clock minus simulator clock [ns]: the smallest (receive time - stamp) of
        the truth samples (publication latency is never negative)."""
        with self.seen.lock:
            pairs = list(self.seen.truth)
        if not pairs:
            return 0
        return min(rx - t.stamp_ns for rx, t in pairs)

    def truth_since(self, sim_ns: int) -> list[SimTruth]:
        """Truth samples stamped from ``sim_ns`` (simulator clock) on, in order."""
        with self.seen.lock:
            return [t for _, t in self.seen.truth if t.stamp_ns >= sim_ns]

    def phase(self) -> str:
        """The bridge's last phase ('' before any)."""
        with self.seen.lock:
            return self.seen.bridge[-1].phase if self.seen.bridge else ""

    def events_of(self, task_id: str) -> list[TaskEvent]:
        """The events of one task."""
        with self.seen.lock:
            return [e for e in self.seen.events if e.task_id == task_id]

    def close(self) -> None:
        """Leave the bus."""
        self.node.close()
