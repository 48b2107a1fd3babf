"""``manus status``: which services are alive and where, bridge health, arm status.

:func:`collect` asks the bus once: the liveliness tokens ``alive/<service>`` (which
services are up), ``where/<service>/<host>/<pid>`` (on which computer and process each
runs), ``disabled/<service>/<why>`` (which are off on purpose, and why: shown ``OFF``),
``health/<service>`` (each service's bad input: payloads that did not decode, per
key, and handler errors; and the scheduling its process runs at), and listens up to
``wait_s`` for the newest ``state/bridge`` (BridgeState) and ``state/status``
(ArmStatus). :func:`format_status` makes one screen of text of it; the same dictionary
is the ``--json`` output.
"""

from __future__ import annotations

import threading
import time
from typing import Any

import zenoh

from manus.can_sharing import DISABLED_TEXT
from manus.errors import SchemaError
from manus.node import Node
from manus.presence import disabled_services
from schemas import endpoints as ep
from schemas.health import NodeHealth
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
    "other_node_frames",
    "preempted_replies",
    "buffered_states",
)
"""BridgeState counters shown under the bridge's health."""


def collect(node: Node, wait_s: float = 1.0) -> dict[str, Any]:
    """The stack's state as seen from ``node`` (see the module docstring).

    Args:
        node: an open node (its prefix selects the arm).
        wait_s: how long to wait for the bridge's and the arm's messages [s].

    Returns:
        ``{"prefix", "services": {name: {"alive", "hosts": [{"host", "pid"}], "disabled":
        why it is off on purpose | None}},
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
    disabled = disabled_services(node.session, keys, timeout=min(1.0, wait_s))
    health = node_health(node, timeout=min(1.0, wait_s))
    got.wait(max(0.0, wait_s - (time.monotonic() - start)))
    names = sorted(set(SERVICES) | alive | set(hosts) | set(disabled), key=_order)
    services = {
        name: {
            "alive": name in alive,
            "hosts": [{"host": h, "pid": p} for h, p in sorted(hosts.get(name, []))],
            "disabled": disabled.get(name),
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
        "bad_input": health,
    }


def node_health(node: Node, timeout: float = 1.0) -> dict[str, dict[str, Any]]:
    """Service -> its bad input (``schemas.health.NodeHealth``): ``bad_payloads`` (total),
    ``by_key`` (key suffix -> count), ``handler_errors``, summed over a service's
    processes; ``scheduling``: pid -> what that process runs at (``rr 10``)."""
    out: dict[str, dict[str, Any]] = {}
    replies = node.session.get(
        node.keys.health_all,
        timeout=timeout,
        target=zenoh.QueryTarget.ALL,  # every service's queryable, not the best match
        consolidation=zenoh.ConsolidationMode.NONE,
    )
    for reply in replies:
        if reply.ok is None:
            continue
        try:
            h = NodeHealth.decode(reply.ok.payload.to_bytes())
        except SchemaError:
            continue
        entry = out.setdefault(
            h.service, {"bad_payloads": 0, "by_key": {}, "handler_errors": 0, "scheduling": {}}
        )
        if h.scheduling:
            entry["scheduling"][str(h.pid)] = h.scheduling
        entry["bad_payloads"] += h.bad_payloads
        entry["handler_errors"] += h.handler_errors
        for key, count in zip(h.bad_keys, h.bad_counts, strict=False):
            name = node.keys.suffix(key)
            entry["by_key"][name] = entry["by_key"].get(name, 0) + count
    return dict(sorted(out.items(), key=lambda kv: _order(kv[0])))


def _order(name: str) -> tuple[int, str]:
    return (SERVICES.index(name) if name in SERVICES else len(SERVICES), name)


def format_status(status: dict[str, Any]) -> str:
    """One screen of text of :func:`collect`'s result."""
    lines = [f"manus status (prefix {status['prefix']})", "", "services:"]
    for name, info in status["services"].items():
        where = ", ".join(f"{h['host']} pid {h['pid']}" for h in info["hosts"]) or "-"
        why = info["disabled"]
        if why is not None and not info["alive"]:
            text = DISABLED_TEXT.get(why, "off on purpose")
            lines.append(f"  {name:<11} {'OFF':<6} {why}: {text}")
            continue
        state = "alive" if info["alive"] else "DOWN"
        runs = status.get("bad_input", {}).get(name, {}).get("scheduling", {})
        how = ", ".join(sorted(set(runs.values())))
        lines.append(f"  {name:<11} {state:<6} {where}" + (f"  ({how})" if how else ""))
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
    bad = {
        n: h
        for n, h in status.get("bad_input", {}).items()
        if h["bad_payloads"] or h["handler_errors"]
    }
    lines += ["", "bad input (payloads that did not decode; handler errors):"]
    if not bad:
        lines.append("  none")
    for name, h in bad.items():
        keys = ", ".join(f"{k} {v}" for k, v in sorted(h["by_key"].items()))
        errors = h["handler_errors"]
        lines.append(f"  {name:<11} {h['bad_payloads']} ({keys or '-'}); {errors} handler errors")
    return "\n".join(lines)


def _fmt(value: Any) -> str:
    return f"{value:.2f}" if isinstance(value, float) else str(value)
