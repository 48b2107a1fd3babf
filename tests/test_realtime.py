"""The scheduling priority of the services on the 60 ms path (manus/realtime.py): the
setting, every thread raised, a clear warning when it is not permitted, the guard
against a real-time thread that never sleeps."""

from __future__ import annotations

import argparse
import ctypes
import os
import subprocess
import sys
from pathlib import Path

import pytest

from manus.errors import ConfigError
from manus.realtime import (
    CAN_EDGE,
    CAP_SYS_NICE,
    DEFAULT,
    ENV,
    RT_TIME_SOFT_US,
    Priority,
    add_realtime_argument,
    describe,
    setting,
)

ROOT = Path(__file__).resolve().parent.parent
PR_CAPBSET_DROP = 24
"""prctl(2): drop a capability from the bounding set (a root process's exec then lacks it)."""

needs_root = pytest.mark.skipif(
    os.geteuid() != 0, reason="raising a priority needs CAP_SYS_NICE (CI runs as root)"
)


def _without_cap_sys_nice() -> None:
    """In the child before exec: CAP_SYS_NICE out of the bounding set (root keeps the
    rest; its RLIMIT_RTPRIO is 0, so a real-time policy is refused as for a user)."""
    libc = ctypes.CDLL(None, use_errno=True)
    if libc.prctl(PR_CAPBSET_DROP, CAP_SYS_NICE, 0, 0, 0) != 0:
        raise OSError(ctypes.get_errno(), "prctl(PR_CAPBSET_DROP, CAP_SYS_NICE)")


def _script(body: str, capable: bool = True) -> subprocess.CompletedProcess[str]:
    """Run ``body`` in a fresh interpreter (its scheduling is its own), logging at INFO;
    ``capable=False``: without CAP_SYS_NICE."""
    head = "import logging, os, threading, time\nlogging.basicConfig(level=logging.INFO)\n"
    head += "from manus.realtime import *\n"
    return subprocess.run(
        [sys.executable, "-c", head + body],
        capture_output=True, text=True, timeout=60, cwd=ROOT,
        preexec_fn=None if capable else _without_cap_sys_nice,
    )  # fmt: skip


def test_the_settings_and_what_is_refused() -> None:
    assert Priority.parse("rr") == Priority("rr", 10) == DEFAULT
    assert Priority.parse(" FIFO:20 ") == Priority("fifo", 20)
    assert Priority.parse("nice") == Priority("nice", -10)
    assert Priority.parse("nice:5") == Priority("nice", 5)
    assert str(Priority.parse("off")) == "off" and str(Priority("rr", 3)) == "rr:3"
    assert Priority("rr", 1).realtime and not Priority("nice", -5).realtime
    for text, why in [
        ("rr:0", "rr level 0 outside 1..99"),
        ("fifo:100", "fifo level 100 outside 1..99"),
        ("nice:-21", "nice level -21 outside -20..19"),
        ("idle", "'idle' is not one of"),
        ("rr:high", "invalid literal"),
        ("off:3", "off level 3 outside 0..0"),
    ]:
        with pytest.raises(ConfigError, match=rf"--realtime='{text}': expected off, rr\[:1..99\]"):
            Priority.parse(text)
        with pytest.raises(ConfigError, match=why):
            Priority.parse(text)


def test_the_command_line_wins_over_the_environment_over_the_default() -> None:
    parser = argparse.ArgumentParser()
    add_realtime_argument(parser)
    assert setting(parser.parse_args([]), env={}) == DEFAULT
    assert setting(parser.parse_args([]), env={}, default=CAN_EDGE) == CAN_EDGE  # on the bus
    assert CAN_EDGE.level > DEFAULT.level  # the bus's processes go first
    assert setting(parser.parse_args([]), env={ENV: "rr:3"}, default=CAN_EDGE) == Priority("rr", 3)
    assert setting(parser.parse_args([]), env={ENV: "nice:-5"}) == Priority("nice", -5)
    assert setting(parser.parse_args(["--realtime", "off"]), env={ENV: "nice:-5"}) == Priority(
        "off"
    )
    with pytest.raises(ConfigError, match=f"{ENV}='rr:200'"):
        setting(parser.parse_args([]), env={ENV: "rr:200"})


def test_describe_reads_what_the_kernel_says() -> None:
    assert describe() == f"normal nice {os.getpriority(os.PRIO_PROCESS, 0)}"
    assert describe(2**22 + 1) == "unknown"  # above pid_max: no such process


@needs_root
def test_every_thread_is_raised_and_threads_made_later_inherit_it() -> None:
    out = _script(
        "before = threading.Thread(target=time.sleep, args=(1.0,)); before.start()\n"
        "print(raise_priority(Priority('rr', 7), 'test'))\n"
        "after = threading.Thread(target=time.sleep, args=(1.0,)); after.start()\n"
        "print(sorted({describe(int(t)) for t in os.listdir('/proc/self/task')}))\n"
        "print(raise_priority(Priority('nice', -4), 'test'))\n"
        "print(sorted({describe(int(t)) for t in os.listdir('/proc/self/task')}))\n"
        "print(raise_priority(Priority('off'), 'test'))\n"
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines() == [
        "rr 7",
        "['rr 7']",
        "normal nice -4",
        "['normal nice -4']",
        "normal nice -4",  # off: left as it was
    ]
    assert "INFO:manus.realtime:test: scheduling rr 7" in out.stderr


@needs_root
def test_a_thread_that_ends_meanwhile_is_skipped_at_every_policy() -> None:
    """A thread listed that has ended by the time its policy is set (ESRCH) is skipped:
    the ``nice`` policy raised ProcessLookupError (a live test's teardown failed so in a
    fresh clone's CI, a Zenoh thread ending as the test's process went back to normal)."""
    out = _script(
        "import manus.realtime as rt\n"
        "listed = rt._threads\n"
        "rt._threads = lambda: [*listed(), 2**22 + 1]  # above pid_max: gone\n"
        "print(raise_priority(Priority('rr', 7), 'test'))\n"
        "print(raise_priority(Priority('nice', 3), 'test'))\n"
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.splitlines() == ["rr 7", "normal nice 3"]


@needs_root
def test_without_the_capability_it_says_what_is_missing_and_runs_on() -> None:
    nice = os.getpriority(os.PRIO_PROCESS, 0)
    out = _script("print(raise_priority(Priority('rr', 10), 'manus bridge'))\n", capable=False)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == f"normal nice {nice}"
    assert (
        "WARNING:manus.realtime:manus bridge: realtime rr:10 not permitted (CAP_SYS_NICE "
        f"missing and RLIMIT_RTPRIO 0 < 10): running at normal nice {nice} "
        "(docs/deployment.md, Real-time priority)"
    ) in out.stderr
    out = _script("print(raise_priority(Priority('nice', -10), 'manus bridge'))\n", capable=False)
    assert out.stdout.strip() == f"normal nice {nice}"
    assert "realtime nice:-10 not permitted (CAP_SYS_NICE missing and RLIMIT_NICE 0 < 30)" in (
        out.stderr
    )


@needs_root
def test_a_real_time_thread_that_never_sleeps_is_put_back_to_normal() -> None:
    """RLIMIT_RTTIME: SIGXCPU after 200 ms of running without sleeping; the process goes
    back to the ordinary policy and lives on (priority 1: below every stack of the suite,
    which preempts this spin)."""
    out = _script(
        "raise_priority(Priority('rr', 1), 'spinner')\n"
        "start = time.monotonic()\n"
        "while describe() == 'rr 1' and time.monotonic() - start < 5.0:\n"
        "    pass\n"
        "print(describe(), sorted({describe(int(t)) for t in os.listdir('/proc/self/task')}))\n"
    )
    nice = os.getpriority(os.PRIO_PROCESS, 0)  # the child's, back under the ordinary policy
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == f"normal nice {nice} ['normal nice {nice}']"
    assert (
        f"a thread ran {RT_TIME_SOFT_US // 1000} ms at real-time priority without sleeping: "
        f"back to normal nice {nice}"
    ) in out.stderr


@needs_root
@pytest.mark.slow  # tests/live_priority.py: a live test's process, its threads, not its children
def test_a_live_test_runs_real_time_and_the_processes_it_starts_do_not() -> None:
    import threading

    from tests.live_priority import LIVE_TEST_PRIORITY

    level = f"rr {LIVE_TEST_PRIORITY.level}"
    assert describe() == level
    seen: list[str] = []
    thread = threading.Thread(target=lambda: seen.append(describe(threading.get_native_id())))
    thread.start()
    thread.join()
    assert seen == [level]
    child = subprocess.run(
        [sys.executable, "-c", "from manus.realtime import describe; print(describe())"],
        capture_output=True, text=True, timeout=60, cwd=ROOT,
    )  # fmt: skip
    assert child.stdout.strip().startswith("normal nice"), child
