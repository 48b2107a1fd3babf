"""A stopped subscriber delays nobody else's traffic, and loses nothing once continued.

The chaos soak saw moves fail with "lost the supervisor's heartbeat" when the recorder
was killed or stopped (docs/deployment.md, Chaos soak), and the first guess was the
router: every publisher of the stack uses blocking congestion control, so a subscriber
that stops reading could block the router's delivery to everyone. This test takes that
worst case: a subscriber process on ``<prefix>/**`` (as the recorder) with a 10 s lease,
so that the router keeps its link the whole time, is SIGSTOPped while the stack's own
publishers (``Node.publisher``) send heartbeats and about 100 times the stack's byte
rate beside them. Every heartbeat sent while it is stopped must reach another
subscriber while it is still stopped (a blocked router would hold them until the
SIGCONT). The router cuts the stopped one off once its queue has stayed full for
``manus.session.BLOCK_CLOSE_US``; a subscriber that is merely slow keeps every message
(blocking congestion control kept: the recorder loses nothing while it is alive).

Live tests (``slow``): they judge a router against time, so they run in a live lane, at
its priority (tests/scheduling.py), not beside a CPU-bound pure test on a loaded machine.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator

import pytest
import zenoh

from manus.node import Node
from manus.session import ZenohSettings, client_settings, open_session
from schemas import endpoints as ep
from schemas.control import Heartbeat
from tests.conftest import eventually, matched_publisher

pytestmark = pytest.mark.slow

SUBSCRIBER = """
import sys, time
from manus.session import client_settings, open_session
endpoint, prefix, lease = sys.argv[1], sys.argv[2], int(sys.argv[3])
session = open_session(client_settings(endpoint, lease_ms=lease))
beats = []
key = prefix + "/heartbeat"
session.declare_subscriber(
    prefix + "/**", lambda s: beats.append(1) if str(s.key_expr) == key else None
)
print("ready", flush=True)
sys.stdin.readline()
time.sleep(1.0)
print(len(beats), flush=True)
session.close()
"""
"""A subscriber of everything under the prefix that prints how many heartbeats it got
once told to stop (a line on stdin)."""


@contextlib.contextmanager
def _subscriber(endpoint: str, prefix: str) -> Iterator[subprocess.Popen[str]]:
    """The :data:`SUBSCRIBER` process (10 s lease), once its subscription reached the
    router; killed on the way out if it still runs."""
    argv = [sys.executable, "-c", SUBSCRIBER, endpoint, prefix, "10000"]
    sub = subprocess.Popen(argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert sub.stdout is not None
        assert sub.stdout.readline().strip() == "ready"
        with open_session(client_settings(endpoint)) as probe:
            # it subscribes to everything under the prefix: this key too, and only it
            matched_publisher(probe, f"{prefix}/probe/stalled").undeclare()
        yield sub
    finally:
        if sub.poll() is None:
            sub.kill()
            sub.communicate()


FILLER = 20_000
"""Bytes of each filler sample: 10 per heartbeat, 100 heartbeats a second: 20 MB/s."""


def test_a_stopped_subscriber_delays_no_one(
    zenoh_settings: ZenohSettings, router_endpoint: str
) -> None:
    prefix = zenoh_settings.prefix
    sent: list[float] = []  # send time of heartbeat seq i [monotonic s]
    with _subscriber(router_endpoint, prefix) as sub:
        with (
            Node("publisher", zenoh_settings, liveliness=False) as node,
            Node("listener", zenoh_settings, liveliness=False) as listener,
        ):
            beats = node.publisher(node.keys(ep.HEARTBEAT))  # the stack's own settings
            filler = node.session.declare_publisher(
                node.keys(ep.SIM_TRUTH), congestion_control=zenoh.CongestionControl.BLOCK
            )
            received: set[int] = set()
            lock = threading.Lock()

            def on_beat(beat: Heartbeat, rx_ns: int) -> None:
                with lock:
                    received.add(beat.seq)

            listener.subscribe(listener.keys(ep.HEARTBEAT), Heartbeat, on_beat, locked=False)
            # then one outside the prefix: declarations of one session reach the router in
            # order, so once that one matches, the heartbeat subscription is known too
            listener.subscribe("probe/listener", Heartbeat, on_beat, locked=False)
            matched_publisher(node.session, "probe/listener").undeclare()
            pad = b"x" * FILLER
            os.kill(sub.pid, signal.SIGSTOP)
            try:
                stopped_at = time.monotonic()
                while time.monotonic() - stopped_at < 3.0:
                    for _ in range(10):
                        filler.put(pad)
                    beats.put(Heartbeat(stamp_ns=time.time_ns(), seq=len(sent),
                                        source="test", ref_seq=0, ref_stamp_ns=0))  # fmt: skip
                    sent.append(time.monotonic())
                    time.sleep(0.01)
                # still stopped: every heartbeat sent until 0.5 s ago has reached the listener
                due = {i for i, t in enumerate(sent) if t < time.monotonic() - 0.5}

                def arrived() -> bool:
                    with lock:
                        return due <= received

                eventually(arrived, 2.0, "the heartbeats sent while a subscriber is stopped")
            finally:
                os.kill(sub.pid, signal.SIGCONT)
        out, _ = sub.communicate("stop\n", timeout=30.0)
    assert sub.returncode == 0
    assert int(out.split()[-1]) <= len(sent), (out, len(sent))  # cut off: it reconnects


def test_a_slow_subscriber_loses_nothing(
    zenoh_settings: ZenohSettings, router_endpoint: str
) -> None:
    """Stopped for 0.5 s at the stack's own byte rate (about 20 kB/s: the queues never
    fill), it keeps its link and gets every heartbeat once continued."""
    prefix = zenoh_settings.prefix
    sent = 0
    with (
        _subscriber(router_endpoint, prefix) as sub,
        Node("publisher", zenoh_settings, liveliness=False) as node,
    ):
        beats = node.publisher(node.keys(ep.HEARTBEAT))
        # the router knows the subscriber (above); this publisher too before it stops
        # (once, under two CPU hogs, it got 1 of 50 when the stop came at once)
        eventually(lambda: bool(getattr(beats._pub.matching_status, "matching", False)), 10.0)
        os.kill(sub.pid, signal.SIGSTOP)
        try:
            for _ in range(50):
                beats.put(Heartbeat(stamp_ns=time.time_ns(), seq=sent, source="test",
                                    ref_seq=0, ref_stamp_ns=0))  # fmt: skip
                sent += 1
                time.sleep(0.01)
        finally:
            os.kill(sub.pid, signal.SIGCONT)
        out, _ = sub.communicate("stop\n", timeout=30.0)
    assert int(out.split()[-1]) == sent, (out, sent)
