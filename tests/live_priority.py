"""A live test's own process at a real-time priority, as the services it starts are.

A live test (marked ``slow``) is often part of the 60 ms loop itself, not only its judge:
the Zenoh router of the ``router_endpoint`` fixture runs in the test's process and
carries every message of the stack the test starts; some tests run the simulator, the
guardian's loop or a replayed bridge on threads of their own. Beside a CPU-bound process
(a pure test on another worker, a CPU hog, another session) those threads wait for a
core like any ordinary one, while the services around them run real-time
(:mod:`manus.realtime`): measured, joint states and echoes that came late through the
test's router stopped moves ("lost the supervisor's heartbeat", 176 ms).

So for the duration of a live test its process runs at :data:`LIVE_TEST_PRIORITY`
(below the services', so they go first), where permitted (else as before, with
:mod:`manus.realtime`'s warning):

- every thread there is, and every thread the test starts (``threading.setprofile``: a
  new thread raises itself when it first runs Python code);
- but not the processes the test starts: the main thread, which starts them, carries
  ``SCHED_RESET_ON_FORK``, so a service begins at the ordinary policy and takes its own
  setting (the planner and recorders stay ordinary, as in a deployment). Threads the main
  thread makes begin ordinary too, until the profile hook raises them (Python threads) or
  :func:`started` does (native ones made while the test's fixtures were set up).

A thread that runs 200 ms without blocking puts the process back to the ordinary policy
(:mod:`manus.realtime`'s ``RLIMIT_RTTIME`` guard); the next live test raises it again.
After a live test, and before a pure one, the process is ordinary again.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
from types import FrameType
from typing import Any

import pytest

from manus.realtime import Priority, describe, raise_priority

LIVE_TEST_PRIORITY = Priority("rr", 5)
"""Below the services' default (``rr:10``), above every ordinary process."""


def _raise_this_thread(frame: FrameType, event: str, arg: Any) -> None:
    """``threading.setprofile`` hook: the new thread takes the live priority at its first
    Python call, then stops profiling."""
    sys.setprofile(None)
    param = os.sched_param(LIVE_TEST_PRIORITY.level)
    with contextlib.suppress(PermissionError):  # raise_priority said so, for the process
        os.sched_setscheduler(0, os.SCHED_RR, param)


def permitted() -> bool:
    """This process may take :data:`LIVE_TEST_PRIORITY` (tried on this thread, undone)."""
    try:
        os.sched_setscheduler(0, os.SCHED_RR, os.sched_param(LIVE_TEST_PRIORITY.level))
    except PermissionError:
        return False
    os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    return True


def _is_realtime() -> bool:
    return describe().split()[0] in ("rr", "fifo")


def enter(item: pytest.Item) -> None:
    """Before a live test: the process at :data:`LIVE_TEST_PRIORITY` (see the module
    docstring)."""
    raise_priority(LIVE_TEST_PRIORITY, f"live test {item.name}")
    if not _is_realtime():
        return
    main = os.sched_param(LIVE_TEST_PRIORITY.level)
    os.sched_setscheduler(0, os.SCHED_RR | os.SCHED_RESET_ON_FORK, main)  # this thread
    threading.setprofile(_raise_this_thread)


def started(item: pytest.Item) -> None:
    """After a live test's fixtures are set up, before it runs: the native threads the
    main thread made meanwhile (a first Zenoh session's runtime) raised too."""
    if not _is_realtime():
        return
    param = os.sched_param(LIVE_TEST_PRIORITY.level)
    for tid in map(int, os.listdir("/proc/self/task")):
        if tid != threading.get_native_id() and not _thread_realtime(tid):
            with contextlib.suppress(ProcessLookupError, PermissionError):  # just ended
                os.sched_setscheduler(tid, os.SCHED_RR, param)


def leave(nice: int) -> None:
    """After a live test: every thread back at the ordinary policy, niceness ``nice``."""
    threading.setprofile(None)  # removes the hook
    if _is_realtime() or any(_thread_realtime(int(t)) for t in os.listdir("/proc/self/task")):
        raise_priority(Priority("nice", nice), "after a live test")


def _thread_realtime(tid: int) -> bool:
    try:
        return os.sched_getscheduler(tid) & ~os.SCHED_RESET_ON_FORK in (
            os.SCHED_RR,
            os.SCHED_FIFO,
        )
    except (ProcessLookupError, PermissionError):
        return False
