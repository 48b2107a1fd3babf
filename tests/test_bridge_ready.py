"""``manus up`` says ``up:`` only once the bridge runs (``manus_stack/bridge_ready.py``):
it follows ``state/bridge`` until ``running``, stops at once at a phase the bridge does
not leave by itself, and at its deadline otherwise, saying the phase and its detail."""

from __future__ import annotations

import dataclasses
import threading
import time

import pytest

from manus.node import Node
from manus.session import ZenohSettings
from manus_stack.bridge_ready import not_running, wait_running
from schemas import endpoints as ep
from schemas.state import BridgeState
from tests.test_sequencer_core import bridge_state


def _follow(settings: ZenohSettings, phases: list[tuple[str, str]], wait_s: float) -> str:
    """Publish ``phases`` (phase, detail), then the last again every 60 ms, as a bridge at
    each sync; what :func:`not_running` says of :func:`wait_running`'s answer."""
    stop = threading.Event()
    with Node("can_bridge", settings) as bridge, Node("up", settings, liveliness=False) as up:
        pub = bridge.publisher(bridge.keys(ep.BRIDGE_STATE))

        def feed() -> None:
            seq = 0
            while not stop.wait(0.06):
                seq += 1
                phase, detail = phases[min(seq // 5, len(phases) - 1)]
                pub.put(bridge_state(phase, seq, detail))

        feeder = threading.Thread(target=feed, daemon=True)
        feeder.start()
        try:
            t0 = time.monotonic()
            state = wait_running(up, t0 + wait_s, lambda: None)
            return not_running(state, time.monotonic() - t0)
        finally:
            stop.set()
            feeder.join(2.0)


def test_up_waits_for_running(zenoh_settings: ZenohSettings) -> None:
    phases = [("waiting_power_up", "bus open"), ("initialising", "joint mode"), ("running", "")]
    assert _follow(zenoh_settings, phases, 20.0) == ""


def test_up_says_why_the_bridge_does_not_run(zenoh_settings: ZenohSettings) -> None:
    t0 = time.monotonic()
    why = _follow(zenoh_settings, [("arm_error", "arm error 4: absolute encoder error")], 20.0)
    assert (
        why == "the bridge stopped starting: phase arm_error (arm error 4: absolute encoder error)"
    )
    assert time.monotonic() - t0 < 10.0  # at once, not at the deadline
    why = _follow(zenoh_settings, [("waiting_power_up", "bus open: waiting for the arm")], 1.0)
    assert why == (
        "the bridge is not running after 1 s: phase waiting_power_up (bus open: waiting for "
        "the arm)"
    )


def test_no_bridge_state_at_all() -> None:
    assert not_running(None, 60.0).startswith(
        "the bridge reported no state within 60 s: it hears no sync from the arm"
    )


def test_a_restarted_bridges_predecessor_does_not_end_the_wait(
    zenoh_settings: ZenohSettings,
) -> None:
    """The last state of a bridge stopped before the wait (``shutdown``), late through the
    router, is not the new bridge's."""
    with (
        Node("can_bridge", zenoh_settings) as bridge,
        Node("up", zenoh_settings, liveliness=False) as up,
    ):
        pub = bridge.publisher(bridge.keys(ep.BRIDGE_STATE))
        stale = dataclasses.replace(bridge_state("shutdown", 9), stamp_ns=time.time_ns())
        since = time.time_ns()
        done = threading.Event()
        result: list[BridgeState | None] = []

        def wait() -> None:
            result.append(wait_running(up, time.monotonic() + 20.0, lambda: None, since))
            done.set()

        waiter = threading.Thread(target=wait, daemon=True)
        waiter.start()
        for _ in range(20):  # late, for a while: the waiter subscribes meanwhile
            pub.put(stale)
            assert not done.wait(0.05), result
        fresh = dataclasses.replace(bridge_state("running", 1), stamp_ns=time.time_ns())
        while not done.wait(0.06):
            pub.put(fresh)
        waiter.join(2.0)
    (state,) = result
    assert state is not None and state.phase == "running"


def test_a_process_that_exits_ends_the_wait(zenoh_settings: ZenohSettings) -> None:
    def died() -> None:
        raise RuntimeError("manus bridge exited with status 1")

    with Node("up", zenoh_settings, liveliness=False) as up, pytest.raises(RuntimeError):
        wait_running(up, time.monotonic() + 20.0, died)
