"""The flight recorder's core: the last seconds of every key, kept until something goes wrong.

:class:`FlightCore` keeps, per key, the samples of the last ``ring_s`` seconds (log time)
in memory, within ``cap_bytes`` in all: when a sample would exceed the cap, the oldest
samples of the key holding the most bytes go first, so a flood on one key (CAN frames,
a runaway publisher) costs that key its history, not the others theirs. When a trigger
fires (:class:`TriggerRules`), the core takes everything it holds, goes on collecting
for ``after_s`` seconds, and hands the whole window back as one :class:`Dump` for the
shell to write (one MCAP file per trigger). A trigger while a dump is collecting joins
that dump (its reason is added); the next file starts with the next trigger after it.

Triggers are edges, not levels: an arm error reported in every cycle fires once, when it
appears. Time comes only from the samples (and :meth:`FlightCore.tick`), so a replayed
stream gives the same dumps.
"""

from __future__ import annotations

import re
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

from manus.errors import ManusError
from schemas.base import Message
from schemas.commands import EStop
from schemas.control import GoalResult
from schemas.endpoints import (
    ESTOP,
    EVENTS,
    FLIGHT_TRIGGER,
    LIVELINESS,
    RESULT,
    STATUS,
)
from schemas.flight import FlightTrigger
from schemas.keys import Keys
from schemas.liveliness import LivelinessChange
from schemas.sequencing import TaskEvent
from schemas.state import ArmStatus
from services.recorder.errors import RecordingError

ENTRY_OVERHEAD = 200
"""Bytes a kept sample costs beyond its payload (the tuple, its integers, the bytes
object's header), counted against the cap; tests/test_flight.py checks it with
``tracemalloc``."""


class Sample(NamedTuple):
    """One kept sample.

    Attributes:
        order: arrival order (keeps the dump in the order received).
        key: full key expression.
        payload: the bytes as they travelled.
        log_ns: receive time [ns].
        publish_ns: publish time from the attachment (query mirrors), else None.
    """

    order: int
    key: str
    payload: bytes
    log_ns: int
    publish_ns: int | None


@dataclass(frozen=True)
class Trigger:
    """Why a dump was made.

    Attributes:
        t_ns: log time of the sample that fired it [ns].
        kind: ``emergency_stop``, ``arm_error``, ``arm_warning``, ``goal_aborted``, ``task_failed``,
            ``liveliness_lost`` or ``request``.
        detail: the message's own words.
    """

    t_ns: int
    kind: str
    detail: str

    @property
    def slug(self) -> str:
        """``kind`` plus a short file-name-safe detail."""
        tail = re.sub(r"[^A-Za-z0-9]+", "-", self.detail).strip("-")[:40]
        return f"{self.kind}-{tail}" if tail else self.kind


@dataclass
class Dump:
    """A window to write: everything held at the trigger plus the seconds after it.

    Attributes:
        triggers: the trigger that opened it and any that fired while it collected.
        start_ns: log time of its oldest sample [ns].
        end_ns: when it stops collecting (trigger + after_s) [ns].
        samples: in arrival order.
        bytes: payload bytes plus the per-sample overhead.
        truncated: samples not added because the dump reached the cap.
    """

    triggers: list[Trigger]
    start_ns: int
    end_ns: int
    samples: list[Sample]
    bytes: int = 0
    truncated: int = 0


@dataclass(frozen=True)
class TriggerRules:
    """What makes the flight recorder write.

    Attributes:
        estop: an engaged ``EStop``.
        arm_error: an ``ArmStatus`` of class error (when it appears).
        warning_codes: ``ArmStatus`` warning codes that fire (when they appear), e.g.
            ``(3,)`` for "motor blocked"; empty: none.
        goal_aborted: a ``GoalResult`` with status aborted.
        task_failed: a ``TaskEvent`` ``failed``.
        liveliness_lost: an ``alive/<service>`` token vanishing (``services``: which ones;
            empty: any).
        services: the services whose disappearance fires.
        request: a ``FlightTrigger`` on ``recorder/trigger``.
    """

    estop: bool = True
    arm_error: bool = True
    warning_codes: tuple[int, ...] = ()
    goal_aborted: bool = True
    task_failed: bool = True
    liveliness_lost: bool = True
    services: tuple[str, ...] = ()
    request: bool = True


@dataclass(frozen=True)
class FlightConfig:
    """Sizes of the flight recorder.

    Attributes:
        prefix: key prefix of the arm.
        ring_s: seconds kept before a trigger [s].
        after_s: seconds collected after it [s].
        cap_bytes: most bytes held (ring and a collecting dump each; the live shell's queue
            included: see ``queue_share``) [B].
        rules: the triggers.
        queue_share: share of ``cap_bytes`` kept for the live shell's queue (0..0.5; the
            ring gets the rest: :attr:`ring_cap_bytes`).
    """

    prefix: str = "manus"
    ring_s: float = 30.0
    after_s: float = 5.0
    cap_bytes: int = 64 * 1024 * 1024
    rules: TriggerRules = field(default_factory=TriggerRules)
    queue_share: float = 0.0

    @property
    def queue_bytes(self) -> int:
        """The live shell's queue's share of the cap [B]."""
        return round(self.cap_bytes * self.queue_share)

    @property
    def ring_cap_bytes(self) -> int:
        """Most bytes the ring (and a collecting dump) holds: the cap minus the queue's
        share [B]."""
        return self.cap_bytes - self.queue_bytes

    def __post_init__(self) -> None:
        if not (self.ring_s > 0 and self.after_s >= 0):
            raise RecordingError(
                f"ring {self.ring_s} s must be > 0 and after {self.after_s} s >= 0"
            )
        if self.cap_bytes < 64 * 1024:
            raise RecordingError(f"memory cap {self.cap_bytes} B must be >= 65536 B (64 KiB)")
        if not 0.0 <= self.queue_share <= 0.5:
            raise RecordingError(f"queue share {self.queue_share} must be in 0..0.5")


@dataclass
class FlightStats:
    """Counters.

    Attributes:
        samples: samples received.
        held: samples held now.
        held_bytes: bytes held now (payloads plus overhead).
        peak_bytes: the most bytes ever held.
        evicted_by_cap: samples dropped early to stay under the cap.
        triggers: triggers fired (joined ones included).
        dumps: dumps completed.
        bad_payloads: trigger-key samples that did not decode.
    """

    samples: int = 0
    held: int = 0
    held_bytes: int = 0
    peak_bytes: int = 0
    evicted_by_cap: int = 0
    triggers: int = 0
    dumps: int = 0
    bad_payloads: int = 0


class FlightCore:
    """Ring of the last seconds per key, triggers, dumps (see the module docstring)."""

    def __init__(self, config: FlightConfig | None = None) -> None:
        self.config = config or FlightConfig()
        self.keys = Keys(self.config.prefix)
        self.stats = FlightStats()
        self._ring: dict[str, deque[Sample]] = {}
        self._bytes: dict[str, int] = {}
        self._index = 0
        self._status: tuple[str, int] = ("none", 0)
        self._dump: Dump | None = None
        self._ring_ns = round(self.config.ring_s * 1e9)
        self._after_ns = round(self.config.after_s * 1e9)
        self._checks: dict[str, Callable[[bytes, int], Trigger | None]] = {
            STATUS: self._status_changed,
            ESTOP: self._estop,
            RESULT: self._result,
            EVENTS: self._task_event,
            LIVELINESS: self._liveliness,
            FLIGHT_TRIGGER: self._request,
        }

    @property
    def collecting(self) -> Dump | None:
        """The dump being collected, if any."""
        return self._dump

    def on_sample(
        self, key: str, payload: bytes, log_ns: int, publish_ns: int | None = None
    ) -> list[Dump]:
        """Keep one sample; returns the dumps it completed (usually none)."""
        done = self.tick(log_ns)
        self.stats.samples += 1
        sample = Sample(self._index, key, payload, log_ns, publish_ns)
        self._index += 1
        self._keep(sample)
        if self._dump is not None:
            self._add_to_dump(sample)
        trigger = self._trigger(self.keys.suffix(key), payload, log_ns)
        if trigger is not None:
            self.stats.triggers += 1
            if self._dump is None:
                held = sorted((s for q in self._ring.values() for s in q), key=lambda s: s.order)
                self._dump = Dump([trigger], held[0].log_ns, log_ns + self._after_ns, [])
                for s in held:
                    self._add_to_dump(s)
            else:
                self._dump.triggers.append(trigger)
        if self._dump is not None and self._after_ns == 0:
            done.append(self._finish())
        return done

    def tick(self, now_ns: int) -> list[Dump]:
        """Forget what is older than the ring; returns the collecting dump once its
        after-window is over (call it when the bus is quiet too)."""
        horizon = now_ns - self._ring_ns
        for key, q in self._ring.items():
            while q and q[0].log_ns < horizon:
                self._forget(key, q)
        if self._dump is not None and now_ns >= self._dump.end_ns:
            return [self._finish()]
        return []

    def flush(self) -> Dump | None:
        """The collecting dump, as it is (at shutdown)."""
        return self._finish() if self._dump is not None else None

    # -- the ring ------------------------------------------------------------------------

    @staticmethod
    def _cost(sample: Sample) -> int:
        return len(sample.payload) + ENTRY_OVERHEAD

    def _keep(self, sample: Sample) -> None:
        q = self._ring.get(sample.key)
        if q is None:
            q = self._ring[sample.key] = deque()
            self._bytes[sample.key] = 0
        cost = self._cost(sample)
        while self.stats.held_bytes + cost > self.config.ring_cap_bytes and self.stats.held:
            biggest = max(self._bytes, key=self._bytes.__getitem__)
            self._forget(biggest, self._ring[biggest])
            self.stats.evicted_by_cap += 1
        q.append(sample)
        self._bytes[sample.key] += cost
        self.stats.held += 1
        self.stats.held_bytes += cost
        self.stats.peak_bytes = max(self.stats.peak_bytes, self.stats.held_bytes)

    def _forget(self, key: str, q: deque[Sample]) -> None:
        cost = self._cost(q.popleft())
        self._bytes[key] -= cost
        self.stats.held -= 1
        self.stats.held_bytes -= cost

    # -- dumps ---------------------------------------------------------------------------

    def _add_to_dump(self, sample: Sample) -> None:
        dump = self._dump
        assert dump is not None
        cost = self._cost(sample)
        if dump.bytes + cost > self.config.ring_cap_bytes:
            dump.truncated += 1
            return
        dump.samples.append(sample)
        dump.bytes += cost

    def _finish(self) -> Dump:
        dump = self._dump
        assert dump is not None
        self._dump = None
        self.stats.dumps += 1
        return dump

    # -- triggers ------------------------------------------------------------------------

    def _decode(self, msg_type: type[Message], payload: bytes) -> Message | None:
        try:
            return msg_type.decode(payload)
        except ManusError:
            self.stats.bad_payloads += 1
            return None

    def _trigger(self, suffix: str, payload: bytes, t_ns: int) -> Trigger | None:
        check = self._checks.get(suffix)
        return check(payload, t_ns) if check is not None else None

    def _status_changed(self, payload: bytes, t_ns: int) -> Trigger | None:
        rules = self.config.rules
        if not (rules.arm_error or rules.warning_codes):
            return None
        st = self._decode(ArmStatus, payload)
        if not isinstance(st, ArmStatus):
            return None
        now, before = (st.msg_class, st.msg_code), self._status
        if st.msg_class != "general":
            self._status = now
        if now == before:
            return None
        detail = f"{st.msg_code} {st.text}"
        if st.msg_class == "error" and rules.arm_error:
            return Trigger(t_ns, "arm_error", detail)
        if st.msg_class == "warning" and st.msg_code in rules.warning_codes:
            return Trigger(t_ns, "arm_warning", detail)
        return None

    def _estop(self, payload: bytes, t_ns: int) -> Trigger | None:
        es = self._decode(EStop, payload) if self.config.rules.estop else None
        if isinstance(es, EStop) and es.engaged:
            return Trigger(t_ns, "emergency_stop", f"{es.source} {es.reason}")
        return None

    def _result(self, payload: bytes, t_ns: int) -> Trigger | None:
        res = self._decode(GoalResult, payload) if self.config.rules.goal_aborted else None
        if isinstance(res, GoalResult) and res.status == "aborted":
            return Trigger(t_ns, "goal_aborted", f"{res.goal_id} {res.reason}")
        return None

    def _task_event(self, payload: bytes, t_ns: int) -> Trigger | None:
        ev = self._decode(TaskEvent, payload) if self.config.rules.task_failed else None
        if isinstance(ev, TaskEvent) and ev.event == "failed":
            return Trigger(t_ns, "task_failed", f"{ev.task_id} {ev.reason}")
        return None

    def _liveliness(self, payload: bytes, t_ns: int) -> Trigger | None:
        rules = self.config.rules
        ch = self._decode(LivelinessChange, payload) if rules.liveliness_lost else None
        if (
            isinstance(ch, LivelinessChange)
            and ch.kind == "alive"
            and not ch.alive
            and (not rules.services or ch.service in rules.services)
        ):
            return Trigger(t_ns, "liveliness_lost", ch.service)
        return None

    def _request(self, payload: bytes, t_ns: int) -> Trigger | None:
        req = self._decode(FlightTrigger, payload) if self.config.rules.request else None
        if isinstance(req, FlightTrigger):
            return Trigger(t_ns, "request", f"{req.source} {req.reason}")
        return None
