"""Scheduling priority of the processes on the arm's 60 ms path (docs/deployment.md,
Real-time priority).

The simulator, the bridge, the guardian, the controller, the sequencer (its heartbeat
echo is on the deadman's path) and the router between them mostly sleep on sockets and
timers, and each has a few milliseconds to answer when it wakes. On a busy computer the
kernel's fair scheduler may let a CPU-bound process run for milliseconds before one of
them gets the core: late joint states and echoes stop a path ("no joint state for 301 ms",
"lost the supervisor's heartbeat"). Each of these processes therefore raises its own
scheduling priority once it has started (:func:`raise_priority`), as ros2_control does
for its control loop:

- ``rr:PRIO`` (the default: :data:`CAN_EDGE`, ``rr:20``, for the simulator, the bridge and
  the guardian; :data:`DEFAULT`, ``rr:10``, for the others): the real-time policy
  ``SCHED_RR`` at PRIO (1..99). The process takes a core from any ordinary process (and
  any of a lower priority) as soon as it wakes.
- ``fifo:PRIO``: ``SCHED_FIFO`` (no round robin between processes of equal priority).
- ``nice:N``: the ordinary policy at niceness N (-20..19): a larger share of a contended
  core, but no promise of when it gets it.
- ``off``: keep whatever the process was started with.

The setting: ``--realtime`` of the command, else ``MANUS_REALTIME`` (:data:`ENV`, the
same for every process), else the process's default. Raising needs ``CAP_SYS_NICE``
(root, or ``cap_add: [SYS_NICE]`` in compose.yaml) or a large enough ``RLIMIT_RTPRIO``
/ ``RLIMIT_NICE``. When it is not permitted the process says so in one warning naming
what is missing and runs on at its normal priority.

A real-time process that never sleeps would starve every ordinary process of its core.
Besides the kernel's own throttling (real-time processes get at most
``/proc/sys/kernel/sched_rt_runtime_us`` of each second, 95 % by default), a process
under ``rr`` or ``fifo`` sets ``RLIMIT_RTTIME`` (as rtkit requires of its clients): a
thread that runs :data:`RT_TIME_SOFT_US` without blocking gets ``SIGXCPU``, on which the
process puts itself back to the ordinary policy and says so; if that does not happen,
the kernel kills it at :data:`RT_TIME_HARD_US` (a dead bridge leaves the arm to the
guardian, which stops it).

Linux only: elsewhere the setting is refused with a warning. The priority applies to
every thread of the process (each thread has its own; threads made later inherit it).
"""

from __future__ import annotations

import argparse
import contextlib
import logging
import os
import resource
import signal
from dataclasses import dataclass
from pathlib import Path
from types import FrameType

from manus.errors import ConfigError

log = logging.getLogger("manus.realtime")

ENV = "MANUS_REALTIME"
"""Environment variable with the setting (the command line's ``--realtime`` wins)."""
POLICIES = ("off", "rr", "fifo", "nice")
RT_PRIORITY = 10
"""Default real-time priority (1..99): above every ordinary process, below the kernel's
interrupt threads (50) and ros2_control's default loop (50)."""
NICE = -10
"""Default niceness of ``nice``."""
RT_TIME_SOFT_US = 200_000
"""A real-time thread that runs this long without blocking [us] gets ``SIGXCPU`` (rtkit's
limit): the process returns to the ordinary policy."""
RT_TIME_HARD_US = 1_000_000
"""... and the kernel kills it at this [us] if it is still real-time."""
CAP_SYS_NICE = 23
"""The capability's bit in ``/proc/<pid>/status``'s ``CapEff``."""
_POLICY_NAMES = {0: "normal", 1: "fifo", 2: "rr", 3: "batch", 5: "idle", 6: "deadline"}
"""``/proc/<pid>/stat``'s policy number -> its name here."""


@dataclass(frozen=True)
class Priority:
    """A scheduling setting (see the module docstring).

    Attributes:
        policy: ``off``, ``rr``, ``fifo`` or ``nice``.
        level: the real-time priority (1..99) for ``rr`` and ``fifo``; the niceness
            (-20..19) for ``nice``; 0 for ``off``.
    """

    policy: str
    level: int = 0

    def __post_init__(self) -> None:
        if self.policy not in POLICIES:
            raise ConfigError(f"realtime policy {self.policy!r} is not one of {list(POLICIES)}")
        low, high = {"rr": (1, 99), "fifo": (1, 99), "nice": (-20, 19)}.get(self.policy, (0, 0))
        if not low <= self.level <= high:
            raise ConfigError(f"realtime {self.policy} level {self.level} outside {low}..{high}")

    @classmethod
    def parse(cls, text: str, source: str = "--realtime") -> Priority:
        """``off``, ``rr``, ``rr:PRIO``, ``fifo[:PRIO]``, ``nice[:N]`` (from ``source``).

        Raises:
            ConfigError: naming ``source``, the text and what is allowed.
        """
        policy, _, level = text.strip().lower().partition(":")
        default = {"rr": RT_PRIORITY, "fifo": RT_PRIORITY, "nice": NICE}.get(policy, 0)
        try:
            return cls(policy, int(level) if level else default)
        except (ConfigError, ValueError) as exc:
            raise ConfigError(
                f"{source}={text!r}: expected off, rr[:1..99], fifo[:1..99] or nice[:-20..19] "
                f"({exc})"
            ) from exc

    @property
    def realtime(self) -> bool:
        """A real-time policy (rr, fifo)."""
        return self.policy in ("rr", "fifo")

    def __str__(self) -> str:
        return self.policy if self.policy == "off" else f"{self.policy}:{self.level}"


DEFAULT = Priority("rr", RT_PRIORITY)
"""The setting when neither ``--realtime`` nor ``MANUS_REALTIME`` gives one: the router,
the controller, the sequencer."""
CAN_EDGE = Priority("rr", 2 * RT_PRIORITY)
"""... and of the processes on the CAN bus (simulator, bridge, guardian): above the rest,
whose message handling (a burst of payloads, a plan check) may take a core for tens of
milliseconds, while the bridge has 20 ms to answer a sync (under ``SCHED_RR`` a process
waits behind every other one of its priority that is running; measured: 463 ms without
the arm's frames during a fuzz of every key, all at one priority)."""


def add_realtime_argument(parser: argparse.ArgumentParser, default: Priority = DEFAULT) -> None:
    """``--realtime POLICY`` (over ``MANUS_REALTIME``, over ``default``)."""
    parser.add_argument(
        "--realtime",
        metavar="POLICY",
        help=f"scheduling priority once started: off, rr[:PRIO], fifo[:PRIO], nice[:N] "
        f"(default: ${ENV}, else {default}; needs CAP_SYS_NICE)",
    )


def setting(
    args: argparse.Namespace, env: dict[str, str] | None = None, default: Priority = DEFAULT
) -> Priority:
    """The command line's ``--realtime``, else ``MANUS_REALTIME``, else ``default``
    (:data:`DEFAULT`, or :data:`CAN_EDGE` for the processes on the CAN bus)."""
    given = getattr(args, "realtime", None)
    if given:
        return Priority.parse(given)
    value = (os.environ if env is None else env).get(ENV, "")
    return Priority.parse(value, ENV) if value.strip() else default


def raise_priority(priority: Priority, who: str) -> str:
    """Put every thread of this process at ``priority``; call from the main thread.

    Args:
        priority: what to ask for.
        who: the process's name for the log (``manus bridge``).

    Returns:
        What the process runs at afterwards (:func:`describe` of this process).
    """
    if priority.policy == "off":
        return describe()
    if not hasattr(os, "sched_setscheduler") or not Path("/proc/self/task").is_dir():
        log.warning("%s: realtime %s not supported on this system: normal priority", who,
                    priority)  # fmt: skip
        return describe()
    try:
        if priority.realtime:
            _guard_rt_time()
        for tid in _threads():
            _apply(tid, priority)
    except PermissionError:
        _restore()
        log.warning("%s: realtime %s not permitted (%s): running at %s (docs/deployment.md, "
                    "Real-time priority)", who, priority, _why_refused(priority),
                    describe())  # fmt: skip
        return describe()
    now = describe()
    log.info("%s: scheduling %s", who, now)
    return now


def describe(pid: int | None = None) -> str:
    """The scheduling of ``pid``'s main thread (this process by default): ``rr 10``,
    ``fifo 10``, ``normal nice -10``; ``unknown`` where ``/proc`` cannot tell."""
    try:
        stat = Path(f"/proc/{pid or os.getpid()}/stat").read_text()
    except OSError:
        return "unknown"
    fields = stat[stat.rindex(")") + 2 :].split()  # fields 3.. of proc(5)
    nice, rt_priority, policy = int(fields[16]), int(fields[37]), int(fields[38])
    name = _POLICY_NAMES.get(policy, f"policy {policy}")
    return f"{name} {rt_priority}" if policy in (1, 2) else f"{name} nice {nice}"


def _threads() -> list[int]:
    return sorted(int(t) for t in os.listdir("/proc/self/task"))


def _apply(tid: int, priority: Priority) -> None:
    with contextlib.suppress(ProcessLookupError):  # a thread that has just ended
        if priority.policy == "nice":
            os.sched_setscheduler(tid, os.SCHED_OTHER, os.sched_param(0))
            os.setpriority(os.PRIO_PROCESS, tid, priority.level)  # one thread on Linux
            return
        policy = os.SCHED_RR if priority.policy == "rr" else os.SCHED_FIFO
        os.sched_setscheduler(tid, policy, os.sched_param(priority.level))


def _restore() -> None:
    """Every thread back to the ordinary policy (the ones raised before a refusal)."""
    for tid in _threads():
        with contextlib.suppress(ProcessLookupError, PermissionError):
            if os.sched_getscheduler(tid) in (os.SCHED_RR, os.SCHED_FIFO):
                os.sched_setscheduler(tid, os.SCHED_OTHER, os.sched_param(0))


def _guard_rt_time() -> None:
    """``RLIMIT_RTTIME`` and the ``SIGXCPU`` handler (see the module docstring)."""
    hard = resource.getrlimit(resource.RLIMIT_RTTIME)[1]
    limit = RT_TIME_HARD_US if hard == resource.RLIM_INFINITY else min(hard, RT_TIME_HARD_US)
    resource.setrlimit(resource.RLIMIT_RTTIME, (min(RT_TIME_SOFT_US, limit), limit))
    signal.signal(signal.SIGXCPU, _ran_too_long)


def _ran_too_long(signum: int, frame: FrameType | None) -> None:
    _restore()
    log.error(
        "a thread ran %d ms at real-time priority without sleeping: back to %s "
        "(a real-time process must not hold a core; docs/deployment.md)",
        RT_TIME_SOFT_US // 1000, describe(),
    )  # fmt: skip


def _why_refused(priority: Priority) -> str:
    if _has_cap_sys_nice():
        return "CAP_SYS_NICE held, but this cgroup has no real-time budget (cpu.rt_runtime_us)"
    if priority.realtime:
        limit = resource.getrlimit(resource.RLIMIT_RTPRIO)[0]
        return f"CAP_SYS_NICE missing and RLIMIT_RTPRIO {limit} < {priority.level}"
    limit = resource.getrlimit(resource.RLIMIT_NICE)[0]  # permits niceness >= 20 - limit
    return f"CAP_SYS_NICE missing and RLIMIT_NICE {limit} < {20 - priority.level}"


def _has_cap_sys_nice() -> bool:
    try:
        status = Path("/proc/self/status").read_text()
    except OSError:
        return False
    for line in status.splitlines():
        if line.startswith("CapEff:"):
            return bool(int(line.split()[1], 16) >> CAP_SYS_NICE & 1)
    return False
