"""The sequencer's live shell: the supervisor API on Zenoh around :class:`SequencerCore`.

Its wiring map (:data:`services.sequencer.wiring.WIRING`): the queryables task control
and status (TaskControl -> TaskStatus: cancel, pause, resume, status); the task events
and, while a task runs, the deadman heartbeat (one per joint state) out; joint states,
bridge states, controller feedback and results and e-stops in. Besides: task submission
(Task -> SubmitReply: the core validates the whole task, asking the planner for every
move, before anything moves; the handler waits for the core's :class:`Reply`) and the
liveliness tokens.

The core's queries (the validation's plan requests included) run one at a time, in order,
on a worker thread (never under the node lock, so the callbacks that carry results keep
flowing); a ticker feeds the core the time every 50 ms (waits, timeouts).
"""

from __future__ import annotations

import logging
import queue
import threading
import uuid
from concurrent.futures import Future

import zenoh

from manus.node import Node, QueryError, now_ns
from manus.session import ZenohSettings
from schemas import endpoints as ep
from schemas.sequencing import SubmitReply, Task, TaskAction, TaskControl
from services.sequencer.actions import Action, Query, Reply
from services.sequencer.config import SequencerConfig
from services.sequencer.core import SequencerCore
from services.sequencer.wiring import WIRING

log = logging.getLogger("manus.sequencer")

TICK_S = 0.05
"""Period of the core's clock tick [s]."""


class SequencerShell:
    """The sequencer on the bus (liveliness token ``<prefix>/alive/sequencer``).

    Args:
        settings: how to reach the bus (its prefix roots the keys).
        config: sequencer settings.
        session: an open session to share (not closed by :meth:`close`).
        query_timeout: how long to wait for each service's answer [s] (a submission: for
            each of its steps, and once more).
    """

    def __init__(
        self,
        settings: ZenohSettings,
        config: SequencerConfig | None = None,
        *,
        session: zenoh.Session | None = None,
        query_timeout: float = 5.0,
    ) -> None:
        self.core = SequencerCore(config)
        self.node = Node("sequencer", settings, session=session, liveliness=False)
        self.query_timeout = query_timeout
        self.submitted = 0
        self.refused = 0
        self._queries: queue.Queue[Query | None] = queue.Queue()
        self._answers: dict[str, Future[SubmitReply]] = {}  # submissions waiting
        self._stop = threading.Event()
        self._publish = WIRING.publishers(self.node)  # before any callback can use it
        WIRING.attach(self.node, self.core, self._do, publish=self._publish)
        self.node.watch_liveliness(self._on_alive)
        self.node.queryable(self.node.keys(ep.SUBMIT), Task, self._on_submit, locked=False)
        self._worker = threading.Thread(target=self._work, name="sequencer-queries", daemon=True)
        self._ticker = threading.Thread(target=self._tick, name="sequencer-tick", daemon=True)
        self._worker.start()
        self._ticker.start()
        self.node.announce()  # alive once it listens and answers

    # -- bus inputs (the wiring map's, under the node lock) ---------------------------------

    def _on_alive(self, service: str, alive: bool) -> None:
        self._do(self.core.on_liveliness(service, alive, now_ns()))

    # -- submit: the core validates the whole task, then starts it -------------------------

    def _on_submit(self, task: Task) -> SubmitReply:
        task_id = uuid.uuid4().hex[:8]
        reply = self._submit(task, task_id)
        with self.node.lock:
            if reply.accepted:
                self.submitted += 1
            else:
                self.refused += 1
        if reply.accepted:
            log.info("task %s (%s): %d steps", task_id, task.name, len(task.steps))
        else:
            log.info("refused a task: %s", "; ".join(reply.errors))
        return reply

    def _submit(self, task: Task, task_id: str) -> SubmitReply:
        """Hand ``task`` to the core and wait for its :class:`Reply` (the query worker
        carries the plan requests meanwhile); withdrawn when it takes longer than
        ``query_timeout`` per step, plus one, plus the core's wait for a starting bridge
        (``bridge_wait_s``)."""
        answer: Future[SubmitReply] = Future()
        wait_s = self.core.config.bridge_wait_s
        bound = self.query_timeout * (len(task.steps) + 1) + wait_s
        try:
            with self.node.lock:
                self._answers[task_id] = answer
                self._do(self.core.submit(task, now_ns(), task_id))
            try:
                return answer.result(timeout=bound)
            except TimeoutError:
                why = f"validation did not finish within {bound:g} s (is the planner overloaded?)"
                with self.node.lock:
                    self._do(self.core.withdraw(task_id, now_ns(), why))
                return answer.result(timeout=0)  # withdrawn, or answered just before
        finally:
            with self.node.lock:
                self._answers.pop(task_id, None)

    # -- outputs -----------------------------------------------------------------------------

    def _do(self, actions: list[Action]) -> None:
        self._publish(actions)  # the Publish actions (an unknown key: WiringError)
        for action in actions:
            if isinstance(action, Query):
                self._queries.put(action)
            elif isinstance(action, Reply):
                answer = self._answers.pop(action.submission, None)
                if answer is not None:
                    answer.set_result(action.reply)

    def _work(self) -> None:
        while True:
            item = self._queries.get()
            if item is None:
                return
            key = self.node.keys(item.suffix)
            try:
                reply = self.node.query(
                    key, item.request, item.reply_type, timeout=self.query_timeout
                )
            except QueryError as exc:
                with self.node.lock:
                    self._do(self.core.on_reply(item.token, None, str(exc), now_ns()))
            else:
                with self.node.lock:
                    self._do(self.core.on_reply(item.token, reply, "", now_ns()))

    def _tick(self) -> None:
        while not self._stop.wait(TICK_S):
            with self.node.lock:
                self._do(self.core.on_tick(now_ns()))

    def close(self) -> None:
        """Stop the threads and leave the bus (a running task's goal is cancelled first)."""
        with self.node.lock:
            if self.core.validating:
                why = "the sequencer is shutting down"
                self._do(self.core.withdraw(self.core.validating, now_ns(), why))
            if self.core.busy:
                _, actions = self.core.control(TaskControl(action=TaskAction.CANCEL), now_ns())
                self._do(actions)
        self._stop.set()
        self._queries.put(None)
        self._worker.join(timeout=self.query_timeout + 1.0)
        self._ticker.join(timeout=1.0)
        self.node.close()

    def __enter__(self) -> SequencerShell:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
