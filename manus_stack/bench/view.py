"""What a Foxglove viewer costs the stack: ``manus bench view``.

Two runs of the same stack (``manus up``'s processes: router, simulator, bridge, planner,
controller, sequencer; no recorder), each ``seconds`` long with the arm idle in joint mode
(the bridge and controller still run their 60 ms cycle): first without a viewer, then with
``manus view`` and a Foxglove WebSocket client subscribed to every channel. Figures of
each run:

- ``missed_windows``: the bridge's own count (target 0 in both);
- ``reply_latency_ms``: the bridge's reply latency of each cycle (``BridgeState``);
- ``state_delivery_ms``: 0x360 arrival (the joint state's stamp) to the joint state
  received by an observer on its own session;
- ``cpu_percent``: CPU of each process over the run (of one core), and in all;
- with the viewer: ``foxglove_messages_per_s`` and ``foxglove_kib_per_s`` received by the
  client, and the viewer's own counters (drops).

Then ``throughput``: the viewer's core and server alone, fed a recording as fast as they
take it with a client connected: messages/s in and out.
"""

from __future__ import annotations

import asyncio
import json
import math
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import psutil

from manus.node import Node
from manus.session import client_settings
from manus_stack.ports import free_port
from manus_stack.up import LocalStack, StackOptions
from schemas.endpoints import BRIDGE_STATE, JOINTS
from schemas.state import BridgeState, JointState

DATA = Path(__file__).resolve().parents[2] / "tests" / "data" / "thesis_square.mcap"


def _ms(samples: list[float]) -> dict[str, float]:
    if not samples:
        return {"p50": math.nan, "p99": math.nan, "max": math.nan, "n": 0}
    a = np.asarray(samples, dtype=float)
    return {
        "p50": round(float(np.percentile(a, 50)), 3),
        "p99": round(float(np.percentile(a, 99)), 3),
        "max": round(float(a.max()), 3),
        "n": len(samples),
    }


class _Client:
    """A Foxglove client subscribed to every channel, counting what arrives."""

    def __init__(self, url: str) -> None:
        self.url = url
        self.messages = 0
        self.bytes = 0
        self.subscribed = 0
        self._stop = threading.Event()
        self._thread = threading.Thread(target=lambda: asyncio.run(self._run()), daemon=True)
        self._thread.start()

    async def _run(self) -> None:
        import websockets

        protocols = [websockets.Subprotocol("foxglove.sdk.v1")]
        deadline = time.monotonic() + 20.0  # manus view has no token: it may still be starting
        while True:
            try:
                ws = await websockets.connect(self.url, subprotocols=protocols, max_size=None)
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise
                await asyncio.sleep(0.2)
        async with ws:
            next_id = 1
            while not self._stop.is_set():
                try:
                    frame = await asyncio.wait_for(ws.recv(), 0.2)
                except TimeoutError:
                    continue
                if isinstance(frame, str):
                    msg = json.loads(frame)
                    if msg.get("op") == "advertise":
                        subs = [{"id": next_id + i, "channelId": c["id"]}
                                for i, c in enumerate(msg["channels"])]  # fmt: skip
                        next_id += len(subs)
                        self.subscribed += len(subs)
                        await ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                elif frame[0] == 1:
                    self.messages += 1
                    self.bytes += len(frame)

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)


def _run_stack(seconds: float, view: bool) -> dict[str, Any]:
    port = free_port()
    with tempfile.TemporaryDirectory(prefix="manus-bench-view-") as tmp:
        opts = StackOptions(
            run_dir=Path(tmp),
            endpoint=f"tcp/127.0.0.1:{free_port()}",
            prefix="benchview",
            record=False,
            flight_ring_s=0.0,
            view=view,
            view_port=port,
        )
        with LocalStack(opts) as stack:
            stack.start(timeout=60.0)
            settings = client_settings(opts.endpoint, prefix=opts.prefix)
            delivery: list[float] = []
            latency: list[float] = []
            last: list[BridgeState] = []
            with Node("bench", settings, liveliness=False) as node:

                def on_joints(js: JointState, rx: int) -> None:
                    delivery.append((rx - js.stamp_ns) / 1e6)

                node.subscribe(node.keys(JOINTS), JointState, on_joints)

                def on_bridge(bs: BridgeState, rx: int) -> None:
                    latency.append(bs.reply_latency_ms)
                    last.append(bs)

                node.subscribe(node.keys(BRIDGE_STATE), BridgeState, on_bridge)
                client = _Client(f"ws://127.0.0.1:{port}") if view else None
                deadline = time.monotonic() + 30.0
                while client is not None and not client.subscribed:
                    if time.monotonic() > deadline:
                        raise RuntimeError("the Foxglove client could not subscribe in 30 s")
                    time.sleep(0.1)
                time.sleep(1.0)  # let the streams settle
                procs = {c.name: psutil.Process(c.proc.pid) for c in stack.children}
                cpu0 = {n: p.cpu_times() for n, p in procs.items()}
                delivery.clear()
                latency.clear()
                missed0 = last[-1].missed_windows if last else 0
                got0 = (client.messages, client.bytes) if client else (0, 0)
                t0 = time.monotonic()
                time.sleep(seconds)
                elapsed = time.monotonic() - t0
                cpu1 = {n: p.cpu_times() for n, p in procs.items()}
                got1 = (client.messages, client.bytes) if client else (0, 0)
                if client is not None:
                    client.close()
            cpu = {
                n: round(100 * ((cpu1[n].user + cpu1[n].system) - (cpu0[n].user + cpu0[n].system))
                         / elapsed, 1)
                for n in procs
            }  # fmt: skip
            out: dict[str, Any] = {
                "seconds": round(elapsed, 1),
                "cycles": len(delivery),
                "missed_windows": (last[-1].missed_windows - missed0) if last else None,
                "reply_latency_ms": _ms(latency),
                "state_delivery_ms": _ms(delivery),
                "cpu_percent": {**cpu, "total": round(sum(cpu.values()), 1)},
            }
            if view:
                out["foxglove_messages_per_s"] = round((got1[0] - got0[0]) / elapsed, 1)
                out["foxglove_kib_per_s"] = round((got1[1] - got0[1]) / 1024 / elapsed, 1)
    return out


def _throughput(passes: int) -> dict[str, Any]:
    from services.recorder.reading import Recording
    from services.viewer.core import ViewerCore
    from services.viewer.server import FoxgloveSink

    recs = list(Recording(DATA).messages())
    core = ViewerCore()
    sink = FoxgloveSink(port=0, urdf=core.urdf, describe_topics=(core.topics.robot_description,))
    for topic, schema, encoding in core.channels():
        sink.advertise(topic, schema, encoding)
    client = _Client(f"ws://127.0.0.1:{sink.port}")
    try:
        deadline = time.monotonic() + 10
        while client.subscribed < len(core.channels()) and time.monotonic() < deadline:
            time.sleep(0.05)
        t0 = time.perf_counter()
        n_in = n_out = 0
        for _ in range(passes):
            core = ViewerCore()
            for r in recs:
                for msg in core.on_sample(r.key, r.payload, r.log_ns):
                    sink.log(msg)
                    n_out += 1
                n_in += 1
        elapsed = time.perf_counter() - t0
        time.sleep(0.5)
        received = client.messages
    finally:
        client.close()
        sink.close()
    return {
        "samples_per_s": round(n_in / elapsed),
        "foxglove_messages_per_s": round(n_out / elapsed),
        "us_per_sample": round(1e6 * elapsed / n_in, 1),
        "sent": n_out,
        "received_by_client": received,
    }


def run(quick: bool = False) -> dict[str, Any]:
    """Both stack runs and the throughput figure."""
    seconds = 10.0 if quick else 60.0
    without = _run_stack(seconds, view=False)
    with_view = _run_stack(seconds, view=True)
    return {
        "without_viewer": without,
        "with_viewer": with_view,
        "throughput": _throughput(2 if quick else 10),
        "load_avg": [round(x, 2) for x in psutil.getloadavg()],
    }
