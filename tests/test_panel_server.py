"""The panel's server without a browser or a bus: what each page message makes it do
(``manus_stack/panel/server.py``), through a real WebSocket, with a bus that records."""

from __future__ import annotations

import asyncio
import json
import threading
import time
from typing import Any

from aiohttp import ClientWebSocketResponse
from aiohttp.test_utils import TestClient, TestServer

from manus_stack.panel.server import PageSettings, PanelServer
from manus_stack.panel.tasks import load_buttons
from manus_stack.panel.view import PanelView


class RecordingBus:
    """Stands in for :class:`~manus_stack.panel.bus.PanelBus`: records what it is asked."""

    def __init__(self) -> None:
        self.lock = threading.Lock()
        self.view = PanelView(load_buttons())
        self.calls: list[str] = []

    def jog(self, axis: str) -> None:
        if axis not in ("up", "down", "left", "right", "forward", "back", "open", "close"):
            raise KeyError(axis)
        self.calls.append(f"jog {axis}")

    def stop_jog(self) -> None:
        self.calls.append("stop")

    def estop(self, engaged: bool) -> None:
        self.calls.append(f"estop {engaged}")

    def control(self, action: str) -> None:
        self.calls.append(f"control {action}")

    def set_level(self, level: int) -> None:
        self.calls.append(f"level {level}")


async def _session(script: Any) -> list[str]:
    bus = RecordingBus()
    server = PanelServer(bus, PageSettings(scan=True, scan_ms=900))  # type: ignore[arg-type]
    async with TestClient(TestServer(server.app)) as client:
        ws = await client.ws_connect("/ws")
        hello = json.loads((await ws.receive()).data)
        assert hello["t"] == "hello" and hello["scan"] and hello["scan_ms"] == 900
        assert [p["id"] for p in hello["pad"]][:2] == ["forward", "back"]
        assert json.loads((await ws.receive()).data)["t"] == "view"
        await script(ws)
        await asyncio.sleep(0.2)  # the server's side of the close
    return bus.calls


def test_a_held_pad_is_forwarded_at_once_and_stopped_when_the_page_goes() -> None:
    async def script(ws: ClientWebSocketResponse) -> None:
        for i in range(3):
            await ws.send_json({"t": "jog", "axis": "up", "at": 1000 + 50 * i})
        await ws.send_json({"t": "release"})
        await ws.send_json({"t": "release"})  # not held: nothing more
        await ws.send_json({"t": "jog", "axis": "left", "at": 1200})
        await ws.close()  # the tab closed with the pad held

    calls = asyncio.run(_session(script))
    assert calls == ["jog up", "jog up", "jog up", "stop", "jog left", "stop"]


def test_a_backlog_of_late_commands_is_not_forwarded() -> None:
    """Commands that sat in a buffer (a network that went silent and came back) arrive
    together, long after the page sent them: dropped; the fresh ones after them pass."""

    async def script(ws: ClientWebSocketResponse) -> None:
        start = time.monotonic() * 1e3  # the page's clock: this process's, here
        await ws.send_json({"t": "jog", "axis": "up", "at": start})
        await asyncio.sleep(0.4)  # the link held the next ones for 400 ms or more
        for i in range(1, 5):
            await ws.send_json({"t": "jog", "axis": "up", "at": start + 50 * i})
        await ws.send_json({"t": "jog", "axis": "up", "at": time.monotonic() * 1e3})  # fresh
        await ws.send_json({"t": "release"})
        await ws.close()

    calls = asyncio.run(_session(script))
    assert calls == ["jog up", "jog up", "stop"]


def test_stop_and_bad_messages_stop_the_pad() -> None:
    async def script(ws: ClientWebSocketResponse) -> None:
        await ws.send_json({"t": "jog", "axis": "down", "at": 10})
        await ws.send_json({"t": "stop"})
        await ws.send_json({"t": "release_stop"})
        await ws.send_json({"t": "jog", "axis": "open", "at": 20})
        await ws.send_json({"t": "jog", "axis": "sideways", "at": 30})  # no such button
        await ws.send_json({"t": "jog", "axis": "close", "at": 40})
        await ws.send_str("not json")
        await ws.send_json({"t": "dance"})
        await ws.send_json({"t": "level", "level": 3})
        await ws.send_json({"t": "control", "action": "pause"})
        await ws.send_json({"t": "control", "action": "explode"})
        await ws.close()

    calls = asyncio.run(_session(script))
    assert calls[:8] == [
        "jog down", "estop True", "stop", "estop False", "jog open", "stop", "jog close", "stop",
    ]  # fmt: skip
    assert sorted(calls[8:]) == ["control pause", "level 3"]  # in threads: any order


def test_done_goes_to_the_sequencer_as_its_done() -> None:
    """The page's Done button: the sequencer's ``done`` through the supervisor API."""

    async def script(ws: ClientWebSocketResponse) -> None:
        await ws.send_json({"t": "control", "action": "done"})
        await ws.close()

    assert asyncio.run(_session(script)) == ["control done"]
