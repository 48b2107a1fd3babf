"""The panel on the bus: the supervisor API and the jog API, and nothing else.

Subscribes to ``sequencer/events``, ``controller/jog_state`` and ``estop`` and watches the
services' liveliness tokens (``alive/*``), feeding :class:`~manus_stack.panel.view.PanelView`;
publishes ``jog`` (one command per message from the page, at once) and ``estop``; queries
``sequencer/submit``, ``sequencer/control``, ``sequencer/status`` and
``controller/jog_level``. Those are exactly the keys of the panel's identity in the
deployed access control (:data:`~manus_stack.panel.keys.PANEL_KEYS`). Its node declares
no liveliness token: the panel is a client, not a service of the stack.
"""

from __future__ import annotations

import itertools
import threading
from collections.abc import Callable

from manus.errors import ConfigError
from manus.node import Node, QueryError, now_ns
from manus.session import ZenohSettings
from manus_stack.panel.jogpad import SOURCE, jog_command, stop_command
from manus_stack.panel.tasks import TaskButton
from manus_stack.panel.view import PanelView
from manus_stack.panel.words import Trouble
from schemas import endpoints as ep
from schemas.commands import EStop
from schemas.control import GoalAck
from schemas.jog import JogLevel, JogState
from schemas.sequencing import SubmitReply, TaskAction, TaskControl, TaskEvent, TaskStatus
from services.sequencer.taskfile import TaskFileError

SUBMIT_TIMEOUT_S = 60.0
"""How long a submission may take: the sequencer plans every move before it answers [s]."""
QUERY_TIMEOUT_S = 3.0
"""How long the other queries may take [s]."""


class PanelBus:
    """The panel's Zenoh side; its callbacks update ``view`` under :attr:`lock`.

    Args:
        settings: how to reach the bus.
        view: the page's model.
        on_change: called (from any thread) after each change of ``view``.
    """

    def __init__(
        self, settings: ZenohSettings, view: PanelView, on_change: Callable[[], None]
    ) -> None:
        self.view = view
        self.lock = threading.Lock()
        self._on_change = on_change
        self._seq = itertools.count()
        self.node = Node(SOURCE, settings, liveliness=False)
        keys = self.node.keys
        self._jog = self.node.publisher(keys(ep.JOG))
        self._estop = self.node.publisher(keys(ep.ESTOP))
        self.node.subscribe(keys(ep.EVENTS), TaskEvent, self._event, locked=False)
        self.node.subscribe(keys(ep.JOG_STATE), JogState, self._jog_state, locked=False)
        self.node.subscribe(keys(ep.ESTOP), EStop, self._estop_seen, locked=False)
        self.node.watch_liveliness(self._alive)  # the tokens already up come first

    def _update(self, change: Callable[[], None]) -> None:
        with self.lock:
            change()
        self._on_change()

    def _event(self, msg: TaskEvent, rx_ns: int) -> None:
        self._update(lambda: self.view.on_event(msg))

    def _jog_state(self, msg: JogState, rx_ns: int) -> None:
        self._update(lambda: self.view.on_jog_state(msg))

    def _estop_seen(self, msg: EStop, rx_ns: int) -> None:
        self._update(lambda: self.view.on_estop(msg))

    def _alive(self, service: str, alive: bool) -> None:
        self._update(lambda: self.view.on_alive(service, alive))

    # -- the jog: published at once, from the page's messages --------------------------------

    def jog(self, axis: str) -> None:
        """Publish the command of the held pad button ``axis`` (KeyError: no such button)."""
        self._jog.put(jog_command(axis, next(self._seq), now_ns()))

    def stop_jog(self) -> None:
        """Publish a stop (the pad released)."""
        self._jog.put(stop_command(next(self._seq), now_ns()))

    def estop(self, engaged: bool) -> None:
        """Engage STOP (the bridge latches it: every motion stops, the task fails) or
        release it."""
        why = "STOP pressed on the panel" if engaged else "released on the panel"
        msg = EStop(stamp_ns=now_ns(), seq=next(self._seq), engaged=engaged, source=SOURCE,
                    reason=why)  # fmt: skip
        self._estop.put(msg)
        # our own publication reaches our subscriber too; set it now all the same, so the
        # page shows it without waiting for the round trip
        self._update(lambda: self.view.on_estop(msg))

    # -- queries: blocking, run them off the event loop -------------------------------------

    def submit(self, button: TaskButton, choice: str) -> None:
        """Submit ``button``'s task (blocks while the sequencer validates it)."""
        try:
            task = button.task(choice)
        except (TaskFileError, ConfigError) as exc:  # a broken or missing task file
            why = str(exc)
            self._update(lambda: self.view.on_not_sent(button, why))
            return
        self._update(lambda: self.view.on_submitting(button, choice))
        try:
            reply = self.node.query(self.node.keys(ep.SUBMIT), task, SubmitReply,
                                    timeout=SUBMIT_TIMEOUT_S)  # fmt: skip
        except QueryError as exc:
            why = str(exc)
            self._update(lambda: self.view.on_not_sent(button, why))
            return
        self._update(lambda: self.view.on_submitted(button, choice, reply))

    def control(self, action: str) -> TaskStatus | None:
        """Pause, resume or cancel the current task (None: the sequencer did not answer)."""
        key = ep.TASK_STATUS if action == TaskAction.STATUS else ep.TASK_CONTROL
        try:
            status = self.node.query(self.node.keys(key), TaskControl(action=action),
                                     TaskStatus, timeout=QUERY_TIMEOUT_S)  # fmt: skip
        except QueryError as exc:
            self._lost(str(exc))
            return None
        self._update(lambda: self.view.on_status(status.task_id, status.state))
        return status

    def set_level(self, level: int) -> GoalAck | None:
        """Set the jog's speed level (None: the controller did not answer)."""
        try:
            return self.node.query(self.node.keys(ep.JOG_LEVEL), JogLevel(level=level),
                                   GoalAck, timeout=QUERY_TIMEOUT_S)  # fmt: skip
        except QueryError as exc:
            self._lost(str(exc))
            return None

    def _lost(self, why: str) -> None:
        self._update(lambda: self.view.on_notice(Trouble.NO_CONNECTION, why))

    def close(self) -> None:
        """Close the node."""
        self.node.close()
