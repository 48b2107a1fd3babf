"""Bridge timing live: ``manus sim`` in another process over its slcan link, the bridge here.

Set-up: a loopback Zenoh router, the simulator as a separate process (``manus sim
--device-file``, its default link: slcan on 127.0.0.1), the bridge shell on python-can's
slcan backend, and a stand-in controller on its own Zenoh session that answers every
joint state with a velocity command (joint 1 at +-5 deg/s, turning every 2 s), so replies
carry real commands.

Figures, over ``cycles`` cycles once the bridge is running (5000 = 5 min by default,
200 with ``--quick``):

- ``reply_latency_ms``: 0x37F arrival (its python-can timestamp) to the reply handed to
  the bus; ``missed_windows``: replies later than 20 ms by that clock, or not latched by
  the simulator (its own count, which also sees the link's transfer time);
- ``state_latency_ms``: 0x360 arrival to the joint state published;
  ``state_delivery_ms``: 0x360 arrival to the joint state received by the controller's
  session (through the router);
- ``cpu_ms_per_cycle``: CPU time of the bridge's receive thread per cycle, and of this
  whole process (router, bridge, controller, Zenoh threads) per cycle;
- health counters of the bridge and the simulator's own lateness, and the load average,
  because the machine may be shared.
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from manus.node import Node
from manus.protocol import BITRATE
from manus.session import client_settings, open_session, router_settings
from manus_stack.ports import free_port
from schemas import endpoints as ep
from schemas.commands import JointVelocityCommand
from schemas.state import JointState
from services.can_bridge.main import GIL_SWITCH_S, open_arm_bus
from services.can_bridge.shell import BridgeShell

CYCLE_S = 0.060


def _ms(samples_ns: list[int]) -> dict[str, float]:
    if not samples_ns:
        return {"p50": math.nan, "p99": math.nan, "max": math.nan, "n": 0}
    a = np.asarray(samples_ns, dtype=float) / 1e6
    return {
        "p50": round(float(np.percentile(a, 50)), 3),
        "p99": round(float(np.percentile(a, 99)), 3),
        "max": round(float(a.max()), 3),
        "n": len(samples_ns),
    }


class _Controller:
    """Answers each valid joint state at once (joint 1 +-5 deg/s, sign every 2 s)."""

    def __init__(self, node: Node) -> None:
        self.node = node
        self.pub = node.publisher(node.keys(ep.JOINT_VELOCITY))
        self.delivery_ns: list[int] = []
        self.seq = 0
        node.subscribe(node.keys(ep.JOINTS), JointState, self._on_state)

    def _on_state(self, js: JointState, rx_ns: int) -> None:
        self.delivery_ns.append(rx_ns - js.stamp_ns)
        if not js.valid:
            return
        sign = 1.0 if (js.seq // 33) % 2 == 0 else -1.0
        self.seq += 1
        self.pub.put(
            JointVelocityCommand(
                stamp_ns=js.stamp_ns,
                seq=self.seq,
                source="bench",
                ref_seq=js.seq,
                velocity=[sign * math.radians(5.0), 0.0, 0.0, 0.0, 0.0, 0.0],
                gripper_velocity=0.0,
            )
        )


def _stop_process(proc: subprocess.Popen[str]) -> str:
    if proc.poll() is None:
        os.kill(proc.pid, signal.SIGTERM)
    try:
        _, err = proc.communicate(timeout=10)
    except subprocess.TimeoutExpired:
        os.kill(proc.pid, signal.SIGKILL)
        _, err = proc.communicate(timeout=5)
    return err


def _sim_stats(err: str) -> dict[str, Any]:
    for line in err.splitlines():
        if line.startswith("stats: "):
            data: dict[str, Any] = json.loads(line[7:])
            return data
    return {}


@dataclass
class _Window:
    """What one measuring window saw: health before and after, samples [ns], CPU [s]."""

    h0: dict[str, Any]
    h1: dict[str, Any]
    replies_ns: list[int]
    states_ns: list[int]
    delivery_ns: list[int]
    cpu_thread_s: float
    cpu_process_s: float
    wall_s: float


def _start_sim(device_file: Path) -> subprocess.Popen[str]:
    """``manus sim`` in its own process, writing its slcan channel to ``device_file``."""
    argv = [sys.executable, "-m", "manus_stack.cli", "sim", "--device-file", str(device_file)]
    return subprocess.Popen(
        [*argv, "--no-zenoh"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True
    )


def _measure(
    shell: BridgeShell,
    controller: _Controller,
    samples: tuple[list[tuple[int, int]], list[tuple[int, int]]],
    n: int,
    deadline: float,
) -> _Window:
    """Wait for ``running`` (until the monotonic ``deadline``), then measure ``n`` cycles.

    ``samples``: the (sync, reply) and (0x360, state) time pairs the shell appends to.
    """
    replies, states = samples
    while shell.core.phase != "running":
        if time.monotonic() > deadline:
            raise RuntimeError(f"bridge not running: {shell.core.phase} {shell.core.detail}")
        time.sleep(0.05)
    thread = shell.thread
    assert thread is not None and thread.ident is not None
    clock = time.pthread_getcpuclockid(thread.ident)
    with shell.lock:
        h0 = dict(vars(shell.core.health))
    i_rep, i_st, i_del = len(replies), len(states), len(controller.delivery_ns)
    cpu_thread0, cpu_proc0, wall0 = (
        time.clock_gettime(clock),
        time.process_time(),
        time.monotonic(),
    )
    limit = wall0 + n * CYCLE_S * 2 + 30.0
    while shell.core.health.cycles - h0["cycles"] < n and time.monotonic() < limit:
        time.sleep(0.2)
    cpu_thread = time.clock_gettime(clock) - cpu_thread0
    cpu_proc = time.process_time() - cpu_proc0
    wall = time.monotonic() - wall0
    with shell.lock:
        h1 = dict(vars(shell.core.health))
    return _Window(
        h0,
        h1,
        [t - s for s, t in replies[i_rep:]],
        [t - r for r, t in states[i_st:]],
        controller.delivery_ns[i_del:],
        cpu_thread,
        cpu_proc,
        wall,
    )


_HEALTH = ("resyncs", "stale_commands", "dropped_frames", "duplicate_frames", "late_frames",
           "garbled_frames", "buffered_syncs")  # fmt: skip
_SIM = ("late_max_ms", "late_mean_ms", "late_over_5ms", "outside_window", "extra_replies")


def _figures(
    w: _Window, replies_sent: int, sim_stats: dict[str, Any], load_before: tuple[float, ...]
) -> dict[str, Any]:
    """The bench's JSON figures (see the module docstring)."""
    done = w.h1["cycles"] - w.h0["cycles"]
    late = sum(1 for x in w.replies_ns if x >= 20_000_000)
    not_latched = replies_sent - int(sim_stats.get("replies_latched", 0))
    return {
        "cycles": done,
        "wall_s": round(w.wall_s, 1),
        "missed_windows": max(late, not_latched),
        "missed_windows_bridge_clock": late,
        "replies_not_latched_by_sim": not_latched,
        "reply_latency_ms": _ms(w.replies_ns),
        "state_latency_ms": _ms(w.states_ns),
        "state_delivery_ms": _ms(w.delivery_ns),
        "cpu_ms_per_cycle": {
            "bridge_thread": round(w.cpu_thread_s * 1e3 / max(done, 1), 3),
            "process": round(w.cpu_process_s * 1e3 / max(done, 1), 3),
        },
        "jitter_ms": round(w.h1["jitter_ms"], 3),
        "bridge": {k: w.h1[k] - w.h0[k] for k in _HEALTH},
        "sim": {k: sim_stats.get(k) for k in _SIM},
        "load_avg_1min": [round(load_before[0], 2), round(os.getloadavg()[0], 2)],
        "cpus": os.cpu_count(),
    }


def run(quick: bool = False, cycles: int | None = None) -> dict[str, Any]:
    """Run the bench; ``cycles`` overrides the default count (5000, quick 200)."""
    n = cycles or (200 if quick else 5000)
    switch_s = sys.getswitchinterval()
    sys.setswitchinterval(GIL_SWITCH_S)  # as `manus bridge` does
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    load_before = os.getloadavg()
    router = open_session(router_settings(endpoint))
    tmp = tempfile.TemporaryDirectory(prefix="manus-bench-bridge-")
    device_file = Path(tmp.name) / "device"
    sim = _start_sim(device_file)
    replies: list[tuple[int, int]] = []
    states: list[tuple[int, int]] = []
    try:
        deadline = time.monotonic() + 30.0
        while not device_file.exists():
            if sim.poll() is not None or time.monotonic() > deadline:
                raise RuntimeError(f"manus sim wrote no device file: {_stop_process(sim)}")
            time.sleep(0.05)
        bus = open_arm_bus("slcan", device_file.read_text().strip(), BITRATE)
        settings = client_settings(endpoint, prefix="bench")
        ctl_node = Node("bench-controller", settings, liveliness=False)
        controller = _Controller(ctl_node)
        shell = BridgeShell(
            bus,
            settings,
            on_reply=lambda s, t: replies.append((s, t)),
            on_state=lambda r, t: states.append((r, t)),
        )
        try:
            shell.start()
            window = _measure(shell, controller, (replies, states), n, deadline)
        finally:
            shell.stop(timeout=3.0)
            replies_sent = shell.core.health.replies
            shell.node.close()
            ctl_node.close()
            bus.shutdown()
        sim_stats = _sim_stats(_stop_process(sim))
    finally:
        if sim.poll() is None:
            _stop_process(sim)
        router.close()
        tmp.cleanup()
        sys.setswitchinterval(switch_s)
    return _figures(window, replies_sent, sim_stats, load_before)
