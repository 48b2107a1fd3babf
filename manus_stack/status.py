"""``manus status``: which services are alive and where, bridge health, arm status.

:func:`collect` asks the bus once: the liveliness tokens ``alive/<service>`` (which
services are up), ``where/<service>/<host>/<pid>`` (on which computer and process each
runs), and listens up to ``wait_s`` for the newest ``state/bridge`` (BridgeState) and
``state/status`` (ArmStatus). :func:`format_status` makes one screen of text of it; the
same dictionary is the ``--json`` output.
"""

from __future__ import annotations

import threading
import time
from typing import Any

from manus.node import Node
from schemas import endpoints as ep
from schemas.keys import SERVICES
from schemas.state import ArmStatus, BridgeState

HEALTH_FIELDS = (
    "cycles",
    "period_ms",
    "jitter_ms",
    "reply_latency_ms",
    "reply_latency_max_ms",
    "missed_windows",
    "stale_commands",
    "resyncs",
    "dropped_frames",
    "duplicate_frames",
    "garbled_frames",
    "late_frames",
    "buffered_syncs",
    "bad_payloads",
)
"""BridgeState counters shown under the bridge's health."""


def collect(node: Node, wait_s: float = 1.0) -> dict[str, Any]:
    """The stack's state as seen from ``node`` (see the module docstring).

    Args:
        node: an open node (its prefix selects the arm).
        wait_s: how long to wait for the bridge's and the arm's messages [s].

    Returns:
        ``{"prefix", "services": {name: {"alive", "hosts": [{"host", "pid"}]}},
        "bridge": BridgeState dict | None, "arm": ArmStatus dict | None}``.
    """
    latest: dict[str, Any] = {}
    got = threading.Event()
    lock = threading.Lock()

    def keep(name: str) -> Any:
        def handler(msg: BridgeState | ArmStatus, rx_ns: int) -> None:
            with lock:
                latest[name] = msg
                if "bridge" in latest and "arm" in latest:
                    got.set()

        return handler

    keys = node.keys
    node.subscribe(keys(ep.BRIDGE_STATE), BridgeState, keep("bridge"), locked=False)
    node.subscribe(keys(ep.STATUS), ArmStatus, keep("arm"), locked=False)
    start = time.monotonic()
    alive = node.alive_services(timeout=min(1.0, wait_s))
    hosts = node.service_hosts(timeout=min(1.0, wait_s))
    got.wait(max(0.0, wait_s - (time.monotonic() - start)))
    names = sorted(set(SERVICES) | alive | set(hosts), key=_order)
    services = {
        name: {
            "alive": name in alive,
            "hosts": [{"host": h, "pid": p} for h, p in sorted(hosts.get(name, []))],
        }
        for name in names
    }
    with lock:
        bridge = latest.get("bridge")
        arm = latest.get("arm")
    return {
        "prefix": keys.prefix,
        "services": services,
        "bridge": bridge.to_dict() if bridge is not None else None,
        "arm": arm.to_dict() if arm is not None else None,
    }


def _order(name: str) -> tuple[int, str]:
    return (SERVICES.index(name) if name in SERVICES else len(SERVICES), name)


def format_status(status: dict[str, Any]) -> str:
    """One screen of text of :func:`collect`'s result."""
    lines = [f"manus status (prefix {status['prefix']})", "", "services:"]
    for name, info in status["services"].items():
        where = ", ".join(f"{h['host']} pid {h['pid']}" for h in info["hosts"]) or "-"
        state = "alive" if info["alive"] else "DOWN"
        lines.append(f"  {name:<11} {state:<6} {where}")
    lines += ["", "bridge:"]
    bridge = status["bridge"]
    if bridge is None:
        lines.append("  no BridgeState received (is the bridge running?)")
    else:
        estop = "  E-STOP LATCHED" if bridge["estop"] else ""
        lines.append(f"  phase {bridge['phase']}{estop}   detail: {bridge['detail'] or '-'}")
        figures = [f"{k} {_fmt(bridge[k])}" for k in HEALTH_FIELDS if k in bridge]
        for i in range(0, len(figures), 4):
            lines.append("  " + ", ".join(figures[i : i + 4]))
    lines += ["", "arm:"]
    arm = status["arm"]
    if arm is None:
        lines.append("  no ArmStatus received")
    else:
        text = arm["text"] or "no message"
        lines.append(f"  mode {arm['mode']}, {arm['msg_class']} {arm['msg_code']}: {text}")
    return "\n".join(lines)


def _fmt(value: Any) -> str:
    return f"{value:.2f}" if isinstance(value, float) else str(value)
