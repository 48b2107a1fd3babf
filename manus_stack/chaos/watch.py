"""The soak's own eyes: one Zenoh node that keeps what the judge needs.

- every sample under the prefix, as (key, 8-byte hash of its payload, receive time
  [wall ns]): the reference the recordings are compared with (the soak's node is a
  subscriber like the recorder, on the same router, so a message the recorder should
  have and lacks is one the router delivered to us);
- each ``sim/truth`` (the simulator's clock and true joint angles) with its receive time,
  which also gives the offset from wall clock to simulator clock;
- the sequencer's task events and the bridge's states;
- every liveliness change (service, up, wall ns), and every change of a process's
  ``where`` token (service, pid, up, wall ns): two processes declare ``alive/recorder``
  (the recorder and the flight recorder), so only the ``where`` token says when *the*
  recorder is on the bus;
- the final events it learnt from ``sequencer/history`` rather than on the bus: like any
  client (docs/architecture.md, Learning how a task ended), once the sequencer's token is
  back after vanishing it reads the tasks' records for a while, and a final event that
  was published while a link or the sequencer's session was down is taken from there.
  :meth:`Watcher.events_of` adds it only to a task of which no final event was received.
"""

from __future__ import annotations

import hashlib
import threading
import time
from dataclasses import dataclass, field

import zenoh

from manus.node import Node, QueryError
from manus.session import ZenohSettings
from schemas import endpoints as ep
from schemas.sequencing import FINAL_EVENTS, HistoryRequest, TaskEvent, TaskHistory
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
    where: list[tuple[str, int, bool, int]] = field(default_factory=list)
    recovered: dict[str, TaskEvent] = field(default_factory=dict)


RECOVER_S = 15.0
"""How long after the sequencer's token came back its history is read [s]."""


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
        self._sequencer_seen = False
        self._recover_until = 0.0  # monotonic [s]
        self._closing = threading.Event()
        self._reader = threading.Thread(target=self._read_history, name="chaos-history")
        self._reader.start()
        self.node.watch_liveliness(self._on_alive)
        self.node.watch_tokens(keys.where_all, self._on_where)

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
        if service == "sequencer" and up:
            if self._sequencer_seen:  # back after vanishing
                self._recover_until = time.monotonic() + RECOVER_S
            self._sequencer_seen = True

    def _on_where(self, key: str, up: bool, rx_ns: int) -> None:
        parts = self.node.keys.suffix(key).split("/")  # where/<service>/<host>/<pid>
        if len(parts) == 4 and parts[3].isdigit():
            with self.seen.lock:
                self.seen.where.append((parts[1], int(parts[3]), up, rx_ns))

    def on_bus(self, service: str, pid: int) -> bool:
        """Whether the process ``pid``'s ``where`` token for ``service`` is up now."""
        with self.seen.lock:
            changes = [up for name, p, up, _ in self.seen.where if (name, p) == (service, pid)]
        return bool(changes) and changes[-1]

    def _read_history(self) -> None:
        """Every 0.5 s while :data:`RECOVER_S` has not passed since the sequencer's
        token came back: keep the final events of its records."""
        while not self._closing.wait(0.5):
            if time.monotonic() > self._recover_until:
                continue
            try:
                history = self.node.query(
                    self.node.keys(ep.HISTORY), HistoryRequest(limit=100), TaskHistory, timeout=2.0
                )
            except QueryError:
                continue
            with self.seen.lock:
                for record in history.tasks:
                    if record.final is not None:
                        self.seen.recovered.setdefault(record.task_id, record.final)

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

    def phase(self, since_ns: int = 0) -> str:
        """The bridge's last phase, if that state is stamped at or after ``since_ns`` [wall
        ns] ('' before any: a bridge restarted since has said nothing yet)."""
        with self.seen.lock:
            last = self.seen.bridge[-1] if self.seen.bridge else None
        return last.phase if last is not None and last.stamp_ns >= since_ns else ""

    def events_of(self, task_id: str) -> list[TaskEvent]:
        """The events of one task received on the bus, and its final event read from
        the sequencer's history when none of them is final."""
        with self.seen.lock:
            events = [e for e in self.seen.events if e.task_id == task_id]
            recovered = self.seen.recovered.get(task_id)
        if recovered is not None and not any(e.event in FINAL_EVENTS for e in events):
            events.append(recovered)
        return events

    def recovered(self, task_id: str) -> bool:
        """Whether the task's final event came from the history, not the bus."""
        with self.seen.lock:
            recovered = task_id in self.seen.recovered
            live = any(e.task_id == task_id and e.event in FINAL_EVENTS for e in self.seen.events)
        return recovered and not live

    def close(self) -> None:
        """Leave the bus."""
        self._closing.set()
        self._reader.join()
        self.node.close()
