"""The life of a service's process: the signals that end it, its heap frozen once started,
its niceness.

Every ``manus`` service's ``run`` installs :func:`wait_for_signal` first (SIGINT and
SIGTERM end it in order: its shell closes, the bridge sends its zeros and 0x370) and calls
:func:`freeze_startup_heap` once its shell is up. Neither needs Zenoh: the node itself
is :mod:`manus.node`. A launcher that starts a service in a session of its own lowers it
with :func:`lower_priority`.
"""

from __future__ import annotations

import contextlib
import gc
import os
import signal
import threading
from pathlib import Path
from types import FrameType

AUTOGROUP = Path("/proc/self/autogroup")
"""Linux's scheduling group of this process's session (``sched_autogroup_enabled``)."""


def lower_priority(nice: int) -> None:
    """Run this process (and what it starts) at niceness ``nice`` (> 0) against the other
    processes of the machine, also those of other sessions.

    Linux with autogroups (``kernel.sched_autogroup_enabled = 1``, the default of most
    distributions) shares the CPU first between sessions, each session a group with the
    group's own niceness (0 unless set), and only then between the processes of a session
    by their niceness. A process that is the only one of its session (``setsid``, as
    ``manus up`` starts every service) would keep a whole group's share whatever its
    niceness: so the group's niceness is set too, where the kernel has autogroups.
    Raising one's own niceness needs no privilege.
    """
    os.nice(nice)
    with contextlib.suppress(OSError):  # no autogroups (kernel, or the file not writable)
        AUTOGROUP.write_text(str(nice))


def freeze_startup_heap() -> None:
    """Collect once, then put every object alive now out of the cyclic collector's reach.

    Call it when a long-running service has finished starting. Imports (NumPy, Pinocchio,
    Zenoh, the schemas) leave tens of thousands of long-lived objects, and each full
    collection walks them all: measured here, a full collection in a planner client took
    5-15 ms, often enough to set the 99th percentile of a plan round trip and to eat
    most of the bridge's 20 ms reply window. Frozen objects (``gc.freeze``) are skipped by
    every later collection; they are still freed by reference counting, and garbage made
    after this call is collected as before.
    """
    gc.collect()
    gc.freeze()


def wait_for_signal(stop: threading.Event | None = None) -> threading.Event:
    """Install SIGINT/SIGTERM handlers that set and return ``stop`` (main thread only)."""
    event = stop or threading.Event()

    def handler(signum: int, frame: FrameType | None) -> None:
        event.set()

    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)
    return event
