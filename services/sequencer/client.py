"""A supervisor client of the sequencer over Zenoh (used by ``manus run`` and ``manus demo``).

Submits a task, follows its events until it ends, and can cancel, pause or resume it.
It watches the sequencer's liveliness token (``<prefix>/alive/sequencer``): when it
vanishes, :meth:`TaskClient.follow` returns at once and :attr:`TaskClient.sequencer_gone`
is set, since no final event will ever come.
A supervisor in another language does the same with plain Zenoh and MessagePack (see
``examples/supervisor.py`` and the JSON Schema in ``schemas/supervisor.schema.json``).
"""

from __future__ import annotations

import queue
import threading
import time
from collections.abc import Callable, Iterable

from manus.node import Node
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
        """The sequencer's liveliness token vanished while following a task (set once; a
        new sequencer does not know the task)."""
        self._watching = False

    def _on_liveliness(self, service: str, alive: bool) -> None:
        if service == "sequencer" and not alive:
            self.sequencer_gone.set()

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

    def submit(self, task: Task, timeout: float = 60.0) -> SubmitReply:
        """Submit ``task`` (the sequencer validates it whole before answering).

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
            The final event, or None when ``stop`` was set, ``timeout`` [s] passed or the
            sequencer's liveliness token vanished (:attr:`sequencer_gone`).
        """
        if not self._watching:  # declared here: a liveliness query right after the
            self._watching = True  # subscriber's declaration may miss tokens
            self.node.watch_liveliness(self._on_liveliness)
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            if (stop is not None and stop.is_set()) or self.sequencer_gone.is_set():
                return None
            if deadline is not None and time.monotonic() >= deadline:
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
