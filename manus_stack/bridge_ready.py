"""Waiting until the bridge runs: what ``manus up`` does before it says ``up:``.

The services' liveliness tokens are up well before the arm is ready: the bridge then
waits for the arm's power-up, enters joint mode and makes its start-up moves
(docs/protocol.md, Start-up), and a task submitted meanwhile would have to wait.
:func:`wait_running` follows ``state/bridge`` (published at every sync) until phase
``running``. It stops early at a phase the bridge does not leave by itself (stopped,
estopped, arm_error, shutdown: ``schemas.state.ON_ITS_WAY_PHASES`` holds the others),
and at the deadline; :func:`not_running` says why, with the phase and its detail. The
bridge publishes its state at every sync it hears (and at every change), so no state at
all means no sync: the arm is off or not on that channel, or the bridge hangs.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from manus.node import Node
from schemas import endpoints as ep
from schemas.state import ON_ITS_WAY_PHASES, BridgePhase, BridgeState

POLL_S = 0.1
"""How often the wait looks at the newest state and calls its ``check`` [s]."""


def wait_running(
    node: Node, deadline: float, check: Callable[[], None], since_ns: int = 0
) -> BridgeState | None:
    """Follow ``state/bridge`` until phase ``running``, a phase the bridge does not leave
    by itself, or the monotonic ``deadline`` [s].

    Args:
        node: an open node (its prefix selects the arm).
        deadline: when to give up (``time.monotonic()`` seconds).
        check: called every :data:`POLL_S` (it raises to end the wait: a process died).
        since_ns: states stamped before this wall-clock time [ns] are ignored: after a
            bridge's restart, its predecessor's last states (``shutdown``) may still be
            on their way through the router.

    Returns:
        The newest bridge state (None: none received).
    """
    newest: list[BridgeState] = []
    got = threading.Event()

    def keep(state: BridgeState, rx_ns: int) -> None:
        if state.stamp_ns < since_ns:
            return
        newest[:] = [state]
        if state.phase == BridgePhase.RUNNING or state.phase not in ON_ITS_WAY_PHASES:
            got.set()

    node.subscribe(node.keys(ep.BRIDGE_STATE), BridgeState, keep, locked=False)
    while not got.wait(POLL_S):
        check()
        if time.monotonic() >= deadline:
            break
    return newest[0] if newest else None


def not_running(state: BridgeState | None, waited_s: float) -> str:
    """Why the bridge is not running ('' when it is), after ``waited_s`` [s]."""
    if state is None:  # it publishes its state at every sync it hears
        return (
            f"the bridge reported no state within {waited_s:.0f} s: it hears no sync from "
            "the arm (is the arm on, the CAN channel and bitrate right?), or it hangs"
        )
    if state.phase == BridgePhase.RUNNING:
        return ""
    detail = f" ({state.detail})" if state.detail else ""
    if state.phase in ON_ITS_WAY_PHASES:
        return f"the bridge is not running after {waited_s:.0f} s: phase {state.phase}{detail}"
    return f"the bridge stopped starting: phase {state.phase}{detail}"
