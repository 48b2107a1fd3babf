"""A supervisor client of the sequencer over Zenoh (used by ``manus run`` and ``manus demo``).

Submits a task, follows its events until it ends, and can cancel, pause or resume it.
It learns how the task ended exactly once, even when the final event was lost on the
way (docs/architecture.md, Learning how a task ended): it watches the sequencer's
liveliness token (``<prefix>/alive/sequencer``), and

- when the token vanishes while this client is still linked to its router, the sequencer
  died or hangs: :meth:`TaskClient.follow` returns at once and
  :attr:`TaskClient.sequencer_gone` is set (no final event may ever come);
- when it vanishes because this client's own link is down (a router restart, a cut
  link: every token vanishes with it), it waits for the token to come back, then reads
  the task's record in ``sequencer/history``: the final event published while the link
  was down is there, exactly as published (:attr:`schemas.sequencing.TaskRecord.final`).
  The same after the token's return from a sequencer whose own session was down.

A supervisor in another language does the same with plain Zenoh and MessagePack (see
``examples/supervisor.py`` and the JSON Schema in ``schemas/supervisor.schema.json``).
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass

import zenoh

from manus.node import Node, QueryError
from schemas import endpoints as ep
from schemas.sequencing import (
    FINAL_EVENTS,
    HistoryRequest,
    SubmitReply,
    Task,
    TaskAction,
    TaskControl,
    TaskEvent,
    TaskHistory,
    TaskStatus,
)
from schemas.state import BridgeState, JointState

LINK_SETTLE_S = 0.25
"""How long after the sequencer's token vanished the client looks whether its own link
went down with it [s] (the session drops its router a few ms after the token)."""
LINK_WAIT_S = 30.0
"""How long :meth:`TaskClient.follow` waits for a lost link (and the sequencer's token)
to come back before it gives up [s]."""
RECHECK_S = 1.0
"""After the sequencer's token came back, how often the task's record is read again
until the task has ended [s] (a final event published while routes were still being
rebuilt reaches no subscriber, but is in the record)."""


def link_up(session: zenoh.Session) -> bool:
    """Whether ``session`` is linked to a router or a peer now."""
    info = session.info
    return bool(info.routers_zid() or info.peers_zid())


def recorded_final(history: TaskHistory, task_id: str) -> TaskEvent | bool | None:
    """The final event of ``task_id`` as the sequencer's history keeps it: the event
    (the task ended), None (it still runs) or False (the sequencer does not know it: a
    new sequencer process, or the task is older than its history)."""
    for record in history.tasks:
        if record.task_id == task_id:
            return record.final
    return False


@dataclass
class _Watch:
    """Where :meth:`TaskClient.follow` stands with the sequencer's token."""

    cut: bool = False
    """the token vanished with this client's own link: wait for both to come back"""
    recheck: float = 0.0
    """when to read the task's record again [monotonic s] (0: no need)"""


class TaskClient:
    """Talks to ``<prefix>/sequencer/*`` through ``node``.

    Args:
        node: an open node (``liveliness=False`` for a plain client).
    """

    def __init__(self, node: Node) -> None:
        self.node = node
        self._events: queue.Queue[TaskEvent] = queue.Queue()
        self._running = 0  # consecutive state/bridge reports in phase running
        self.bridge_phase = ""
        node.subscribe(node.keys(ep.EVENTS), TaskEvent, self._on_event, locked=False)
        self._valid_states = 0  # valid joint states since the bridge entered running
        node.subscribe(node.keys(ep.BRIDGE_STATE), BridgeState, self._on_bridge, locked=False)
        node.subscribe(node.keys(ep.JOINTS), JointState, self._on_joints, locked=False)
        self.sequencer_gone = threading.Event()
        """The sequencer died or hangs while following a task: its liveliness token
        vanished while this client's link was up, or it came back not knowing the task
        (a new sequencer process)."""
        self.link_lost = False
        """:meth:`follow` gave up: the link stayed down for :data:`LINK_WAIT_S`."""
        self.recovered: TaskEvent | None = None
        """The last final event read from ``sequencer/history`` rather than received."""
        self._vanished = 0.0  # monotonic time the sequencer's token vanished (0: it is up)
        self._returned = threading.Event()  # the token came back after vanishing
        self._watching = False

    def _on_liveliness(self, service: str, alive: bool) -> None:
        if service != "sequencer":
            return
        if not alive:
            self._vanished = time.monotonic()
        elif self._vanished:
            self._vanished = 0.0
            self._returned.set()

    def _on_bridge(self, state: BridgeState, rx_ns: int) -> None:
        self.bridge_phase = state.phase
        self._running = self._running + 1 if state.phase == "running" else 0
        if not self._running:
            self._valid_states = 0

    def _on_joints(self, state: JointState, rx_ns: int) -> None:
        if state.valid and self._running:
            self._valid_states += 1

    def _on_event(self, event: TaskEvent, rx_ns: int) -> None:
        self._events.put(event)

    def wait_for_services(self, names: Iterable[str], timeout: float) -> list[str]:
        """Wait up to ``timeout`` [s] for the liveliness tokens of ``names``; the missing."""
        wanted = set(names)
        deadline = time.monotonic() + timeout
        while True:
            missing = sorted(wanted - self.node.alive_services(timeout=0.5))
            if not missing or time.monotonic() >= deadline:
                return missing
            time.sleep(0.1)

    def wait_for_arm(self, timeout: float) -> str:
        """Wait up to ``timeout`` [s] until the bridge has reported phase ``running`` twice
        in a row and two valid joint states have followed (the arm is powered up and in
        joint mode; the sequencer, on the same streams, has heard them too). Returns the
        last phase seen ('' when none)."""
        deadline = time.monotonic() + timeout
        while (self._running < 2 or self._valid_states < 2) and time.monotonic() < deadline:
            time.sleep(0.05)
        return self.bridge_phase

    def submit(self, task: Task, timeout: float = 120.0) -> SubmitReply:
        """Submit ``task`` (the sequencer validates it whole before answering, and holds it
        first while the bridge is still starting: at most its ``bridge_wait_s``).

        Raises:
            manus.node.QueryError: no sequencer answered within ``timeout`` [s].
        """
        return self.node.query(self.node.keys(ep.SUBMIT), task, SubmitReply,
                               timeout=timeout)  # fmt: skip

    def control(self, action: str, task_id: str = "", timeout: float = 5.0) -> TaskStatus:
        """Cancel, pause, resume (or status of) a task."""
        request = TaskControl(action=action, task_id=task_id)
        key = ep.TASK_STATUS if action == TaskAction.STATUS else ep.TASK_CONTROL
        return self.node.query(self.node.keys(key), request, TaskStatus, timeout=timeout)

    def history(self, limit: int = 10, timeout: float = 5.0) -> TaskHistory:
        """The most recent tasks, newest first (``sequencer/history``)."""
        request = HistoryRequest(limit=limit)
        return self.node.query(self.node.keys(ep.HISTORY), request, TaskHistory, timeout=timeout)

    def follow(
        self,
        task_id: str,
        on_event: Callable[[TaskEvent], None],
        *,
        stop: threading.Event | None = None,
        timeout: float | None = None,
    ) -> TaskEvent | None:
        """Pass each event of ``task_id`` to ``on_event`` until the task ends.

        Returns:
            The final event (received, or read from ``sequencer/history`` when it was lost
            on the way: :attr:`recovered`), or None when ``stop`` was set, ``timeout`` [s]
            passed, the sequencer died or hangs (:attr:`sequencer_gone`) or the link stayed
            down for :data:`LINK_WAIT_S` (:attr:`link_lost`).
        """
        if not self._watching:  # declared here: a liveliness query right after the
            self._watching = True  # subscriber's declaration may miss tokens
            self.node.watch_liveliness(self._on_liveliness)
        deadline = None if timeout is None else time.monotonic() + timeout
        watch = _Watch()
        while True:
            if (stop is not None and stop.is_set()) or (
                deadline is not None and time.monotonic() >= deadline
            ):
                return None
            verdict = self._check_sequencer(task_id, watch)
            if isinstance(verdict, TaskEvent):
                self.recovered = verdict
                on_event(verdict)
                return verdict
            if not verdict:
                return None
            try:
                event = self._events.get(timeout=0.1)
            except queue.Empty:
                continue
            if event.task_id != task_id:
                continue
            on_event(event)
            if event.event in FINAL_EVENTS:
                return event

    def _check_sequencer(self, task_id: str, watch: _Watch) -> TaskEvent | bool:
        """What the sequencer's token says: True (go on following), False (give up:
        :attr:`sequencer_gone` or :attr:`link_lost` set) or the task's final event read
        from its record."""
        vanished = self._vanished
        if vanished and not watch.cut:
            watch.cut = self._link_cut()
            if not watch.cut:
                self.sequencer_gone.set()
                return False
        if vanished and time.monotonic() - vanished > LINK_WAIT_S:
            if link_up(self.node.session):
                self.sequencer_gone.set()  # the link came back, the sequencer did not
            else:
                self.link_lost = True
            return False
        if self._returned.is_set():
            self._returned.clear()
            watch.cut, watch.recheck = False, time.monotonic()
        if not watch.recheck or time.monotonic() < watch.recheck:
            return True
        final = self._read_record(task_id)
        if final is False:  # a new sequencer: it does not know the task
            self.sequencer_gone.set()
            return False
        if isinstance(final, TaskEvent):
            return final
        watch.recheck = time.monotonic() + RECHECK_S
        return True

    def _link_cut(self) -> bool:
        """The sequencer's token vanished: whether this client's own link went down
        (looked at for :data:`LINK_SETTLE_S`), rather than the sequencer."""
        end = self._vanished + LINK_SETTLE_S
        while True:
            if not link_up(self.node.session):
                return True
            if not self._vanished:  # back already
                return True
            if time.monotonic() >= end:
                return False
            time.sleep(0.02)

    def _read_record(self, task_id: str) -> TaskEvent | bool | None:
        """:func:`recorded_final` of ``task_id`` (None as well when nobody answers)."""
        try:
            history = self.history(limit=100, timeout=2.0)
        except QueryError:
            return None
        return recorded_final(history, task_id)
