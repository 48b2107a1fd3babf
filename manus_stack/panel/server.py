"""The panel's web server (aiohttp): the page, its files, and one WebSocket per page.

The page and the server speak JSON over the WebSocket ``/ws``. The page sends:

- ``{"t": "jog", "axis": NAME, "at": MS}`` while a pad button is held, every
  :data:`~manus_stack.panel.jogpad.REPEAT_MS` (``at``: when, on the page's monotonic
  clock): each is published as a jog command at once, so the stream is the page's own:
  when the page or the network goes silent, the stream stops and the controller's jog
  deadman (150 ms) stops the arm; one that arrives late (it sat in a buffer:
  :class:`~manus_stack.panel.jogpad.Lateness`) is not forwarded;
- ``{"t": "release"}`` when the button is let go: a stop at once;
- ``{"t": "stop"}`` (STOP) and ``{"t": "release_stop"}``: the e-stop, engaged or released;
- ``{"t": "task", "id": ID, "object": NAME}``, ``{"t": "control", "action": A}`` (pause,
  resume, cancel, done: the person ends the follow step that holds, the drink's hold at
  the mouth) and ``{"t": "level", "level": N}``.

A socket that closes (the tab closed, the page left, the WebSocket's ping unanswered for
:data:`HEARTBEAT_S`) while its pad was held publishes a stop at once; when the last page
goes, a task it started is paused (nobody could press STOP). A message the server does not
understand stops the pad too. The server sends ``{"t": "hello", ...}`` (the buttons, the
pad, the page's settings) and then ``{"t": "view", ...}`` (:meth:`PanelView.snapshot`) on
every change and every :data:`KEEPALIVE_S`, so that a page that hears nothing for longer
knows its connection is gone.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import time
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from aiohttp import WSMsgType, web

from manus_stack.panel.bus import PanelBus
from manus_stack.panel.jogpad import AXES, LABELS, REPEAT_MS, Lateness
from manus_stack.panel.words import Trouble
from schemas.sequencing import TaskAction

log = logging.getLogger(__name__)

STATIC = Path(__file__).resolve().parent / "static"
"""The page's files (plain HTML, CSS and JavaScript modules: no build step)."""
HEARTBEAT_S = 1.0
"""The server pings each page this often; no answer within half of it closes the socket."""
KEEPALIVE_S = 1.0
"""A view is sent at least this often [s]."""
STATUS_EVERY_S = 1.0
"""While a task is shown, its state is read from the sequencer this often [s] (a final
event lost on the way must not leave it shown as running)."""


@dataclass(frozen=True)
class PageSettings:
    """What the page is told in its ``hello``.

    Attributes:
        scan: start in switch-scanning mode.
        scan_ms: how long each control stays highlighted when scanning [ms].
    """

    scan: bool = False
    scan_ms: int = 1500


class PanelServer:
    """The web side of the panel.

    Args:
        bus: the panel's bus side (its view is what the pages show).
        settings: the pages' settings.
    """

    def __init__(self, bus: PanelBus, settings: PageSettings) -> None:
        self.bus = bus
        self.settings = settings
        self.sockets: set[web.WebSocketResponse] = set()
        self._changed = asyncio.Event()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._own_tasks: set[str] = set()
        self._jobs: set[asyncio.Task[object]] = set()
        self.app = web.Application()
        self.app.router.add_get("/", self._index)
        self.app.router.add_get("/ws", self._socket)
        self.app.router.add_static("/static", STATIC)
        self.app.cleanup_ctx.append(self._background)

    def changed(self) -> None:
        """The view changed (called from any thread)."""
        if self._loop is not None:
            self._loop.call_soon_threadsafe(self._changed.set)

    async def _background(self, app: web.Application) -> AsyncIterator[None]:
        self._loop = asyncio.get_running_loop()
        tasks = [asyncio.create_task(self._broadcast()), asyncio.create_task(self._watch())]
        yield
        for task in tasks:
            task.cancel()
        for task in tasks:
            with contextlib.suppress(asyncio.CancelledError):
                await task

    async def _index(self, request: web.Request) -> web.FileResponse:
        return web.FileResponse(STATIC / "index.html", headers={"Cache-Control": "no-cache"})

    # -- to the pages ------------------------------------------------------------------------

    def _view(self) -> str:
        with self.bus.lock:
            return json.dumps(self.bus.view.snapshot())

    async def _broadcast(self) -> None:
        while True:
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self._changed.wait(), KEEPALIVE_S)
            self._changed.clear()
            text = self._view()
            for ws in list(self.sockets):
                with contextlib.suppress(ConnectionError, RuntimeError):
                    await ws.send_str(text)

    async def _watch(self) -> None:
        """Read the shown task's state now and then (a lost final event)."""
        while True:
            await asyncio.sleep(STATUS_EVERY_S)
            with self.bus.lock:
                shown = self.bus.view.task is not None
            if shown:
                await asyncio.to_thread(self.bus.control, TaskAction.STATUS)

    # -- from the pages ----------------------------------------------------------------------

    async def _socket(self, request: web.Request) -> web.WebSocketResponse:
        ws = web.WebSocketResponse(heartbeat=HEARTBEAT_S, compress=False)
        await ws.prepare(request)
        with self.bus.lock:
            buttons = self.bus.view.buttons_json()
        hello = {
            "t": "hello",
            "buttons": buttons,
            "pad": [{"id": axis, "label": LABELS[axis]} for axis in AXES],
            "repeat_ms": REPEAT_MS,
            "scan": self.settings.scan,
            "scan_ms": self.settings.scan_ms,
        }
        await ws.send_str(json.dumps(hello))
        await ws.send_str(self._view())
        self.sockets.add(ws)
        held = False
        lateness = Lateness()
        try:
            async for msg in ws:
                if msg.type != WSMsgType.TEXT:
                    break
                held = self._handle(msg.data, held, lateness)
        finally:
            self.sockets.discard(ws)
            if lateness.dropped:
                log.warning("panel: a page's %d late pad messages were not forwarded",
                            lateness.dropped)  # fmt: skip
            if held:
                self.bus.stop_jog()  # the page went while its pad was held: stop now
            if not self.sockets:
                await self._nobody_left()
        return ws

    def _handle(self, text: str, held: bool, lateness: Lateness) -> bool:
        """One message from a page; whether its pad is held afterwards."""
        try:
            data: Any = json.loads(text)
            kind = data["t"]
            if kind == "jog":
                if lateness.stale(float(data["at"]), time.monotonic() * 1e3):
                    return held  # sat in a buffer: not forwarded (Lateness)
                self.bus.jog(str(data["axis"]))
                return True
            if kind == "release":
                if held:
                    self.bus.stop_jog()
                return False
            if kind == "stop":
                self.bus.estop(True)
                if held:
                    self.bus.stop_jog()
                return False
            self._request(kind, data)
        except (ValueError, KeyError, TypeError) as exc:
            log.warning("panel: bad message from a page: %s (%r)", exc, text[:200])
            if held:
                self.bus.stop_jog()
            with self.bus.lock:
                self.bus.view.on_notice(Trouble.UNKNOWN, f"bad message from the page: {exc}")
            self.changed()
            return False
        return held

    def _request(self, kind: str, data: Any) -> None:
        """A message that does not touch the pad (ValueError: an unknown one)."""
        if kind == "release_stop":
            self.bus.estop(False)
        elif kind == "task":
            self._start(str(data["id"]), str(data.get("object", "")))
        elif kind == "control" and data["action"] in ("pause", "resume", "cancel", "done"):
            self._off_loop(self.bus.control, str(data["action"]))
        elif kind == "level":
            self._off_loop(self.bus.set_level, max(1, int(data["level"])))
        else:
            raise ValueError(f"unknown message {kind!r}")

    def _start(self, button_id: str, choice: str) -> None:
        button = next((b for b in self.bus.view.buttons if b.id == button_id), None)
        if button is None:
            raise ValueError(f"no task button {button_id!r}")

        def submit() -> None:
            self.bus.submit(button, choice)
            with self.bus.lock:
                task = self.bus.view.task
                if task is not None and task.button is button:
                    self._own_tasks.add(task.task_id)

        self._off_loop(submit)

    def _off_loop(self, fn: Callable[..., object], *args: Any) -> None:
        """Run ``fn(*args)`` (a query: it blocks) in a thread; the loop goes on."""
        job = asyncio.create_task(asyncio.to_thread(fn, *args))
        self._jobs.add(job)
        job.add_done_callback(self._jobs.discard)

    async def _nobody_left(self) -> None:
        """No page is open: pause a task the panel started (nobody could press STOP)."""
        with self.bus.lock:
            task = self.bus.view.task
            ours = task is not None and task.task_id in self._own_tasks
            running = task is not None and task.state == "running"
        if ours and running:
            log.warning("panel: the last page closed while its task runs: pausing it")
            await asyncio.to_thread(self.bus.control, TaskAction.PAUSE)


async def serve(
    server: PanelServer, port: int, stop: asyncio.Event, ready: Callable[[], None]
) -> None:
    """Serve on 127.0.0.1:``port`` until ``stop`` is set; ``ready()`` once it listens."""
    runner = web.AppRunner(server.app, access_log=None)
    await runner.setup()
    site = web.TCPSite(runner, "127.0.0.1", port)
    await site.start()
    ready()
    try:
        await stop.wait()
    finally:
        await runner.cleanup()
