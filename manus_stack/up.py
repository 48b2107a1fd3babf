"""The whole stack on one machine, each service its own process (``manus up``, ``manus demo``).

Order: a Zenoh router on loopback (``manus router``, a Python session in router mode),
``manus record`` (waited for: its token is up once it listens, so the recording holds
every service's whole life, from the simulator's power-up and the bridge's first cycle
to their shutdown, and ``manus replay --check`` can replay it through a core), the
simulator, an slcan adapter on 127.0.0.1 (``manus sim``, with its objects and its camera;
``--link pty`` in ``sim_args``: on a pseudo-terminal; skipped with a real arm),
``manus bridge`` on that channel (or the real CAN interface), ``manus guardian`` beside it
(the simulator's second node; on a real arm its own channel, else the bridge's if it may
be shared, else it stays off: ``manus_stack.guardian_can``), ``manus planner``,
``manus controller`` and ``manus sequencer``, then
the flight recorder (``manus record --ring``, files under ``<run dir>/flight``; last, so
that it is stopped first and the orderly shutdown of the others is no fault) and, with
``view``, ``manus view``. Every child is a client of the router (``MANUS_ZENOH_CONNECT``),
writes its output to ``<run dir>/logs/<name>.log`` and runs in its own session, so a
Ctrl-C reaches only this process, which then stops the children in reverse order (the
recorder last but the router), each by its pid (SIGINT, then SIGKILL after a grace
period).

:class:`LocalStack` waits until every started service's liveliness token is up (or its
``disabled`` token), and :meth:`LocalStack.wait_running` until the bridge runs.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO

from manus.errors import ManusError
from manus.node import Node
from manus.presence import disabled_services
from manus.process import lower_priority
from manus.realtime import ENV, describe
from manus.session import client_settings
from manus.validity import warm_up
from manus_stack.bridge_ready import not_running, wait_running
from manus_stack.forks import Forked, forkable
from manus_stack.guardian_can import GuardianCan, guardian_can
from manus_stack.ports import port_in_use

LIVELINESS = {
    "sim": "simulator",
    "bridge": "can_bridge",
    "planner": "planner",
    "controller": "controller",
    "sequencer": "sequencer",
    "record": "recorder",
    "guardian": "guardian",
    "flight": "recorder",  # the flight recorder runs as a second recorder process
}
"""``manus`` subcommand -> the liveliness name its node declares."""

NICE = {"view": 10}
"""Niceness of the services off the 60 ms loop: the viewer's only (the router cuts a
starved subscriber off after 50 ms of a full queue: a planner or recorder at 5 lost its
token or messages). Those on the loop raise their own priority (:mod:`manus.realtime`)."""


class StackError(ManusError):
    """The stack could not be brought up (names the service and its log)."""


@dataclass
class Child:
    """One started process."""

    name: str
    argv: list[str]
    log: Path
    proc: subprocess.Popen[bytes] | Forked
    stream: IO[bytes] | None = None


@dataclass
class StackOptions:
    """What to start, where.

    Attributes:
        run_dir: directory for logs, the device file and the recording.
        endpoint: the router's loopback endpoint.
        prefix: key prefix of the arm.
        can_interface: python-can interface of a real arm (empty: the simulator).
        can_channel: its channel.
        guardian_interface: python-can interface of the guardian's own channel (default:
            the bridge's).
        guardian_channel: the guardian's own channel (a second adapter on the arm's bus;
            default: the bridge's, when the interface lets several processes share it).
        record: start the recorder (``manus record``) first.
        guardian: start ``manus guardian`` beside the bridge (on the simulator's second
            node, or see ``guardian_channel``).
        sim_args: extra arguments of ``manus sim``.
        flight_ring_s: seconds the flight recorder keeps (0, or ``record`` off: none).
        view: start ``manus view`` (the Foxglove WebSocket server).
        view_port: its port.
        objects: the simulator's objects (``manus sim --objects``: ``default``, ``none``
            or a file), which its camera reports on ``perception/objects``.
        realtime: ``MANUS_REALTIME`` of the children (empty: as in this environment):
            the scheduling the ones on the 60 ms path take (:mod:`manus.realtime`).
    """

    run_dir: Path
    endpoint: str = "tcp/127.0.0.1:7447"
    prefix: str = "manus"
    can_interface: str = ""
    can_channel: str = ""
    guardian_interface: str = ""
    guardian_channel: str = ""
    record: bool = True
    guardian: bool = True
    sim_args: list[str] = field(default_factory=list)
    flight_ring_s: float = 30.0
    view: bool = False
    view_port: int = 8765
    objects: str = "default"
    realtime: str = ""

    @property
    def flight_dir(self) -> Path:
        """Where the flight recorder writes."""
        return self.run_dir / "flight"

    @property
    def recording(self) -> Path:
        """Where the recorder writes."""
        return self.run_dir / "recording.mcap"

    @property
    def device_file(self) -> Path:
        """Where the simulator writes its adapter's channel (a socket URL or a pty)."""
        return self.run_dir / "sim.device"


class LocalStack:
    """Starts, watches and stops the stack's processes (see the module docstring).

    Args:
        options: what to start and where.
    """

    def __init__(self, options: StackOptions) -> None:
        self.options = options
        self.children: list[Child] = []
        self.device = ""
        self.disabled: dict[str, str] = {}
        """Liveliness name -> why that service is off on purpose (its ``disabled`` token)."""
        self.notes: list[str] = []  # what describe() says besides the processes

    def _env(self) -> dict[str, str]:
        env = dict(os.environ)
        for key in ("MANUS_ZENOH_CONFIG", "MANUS_ZENOH_MODE", "MANUS_ZENOH_LISTEN"):
            env.pop(key, None)
        env["MANUS_ZENOH_CONNECT"] = self.options.endpoint
        env["MANUS_PREFIX"] = self.options.prefix
        env["PYTHONUNBUFFERED"] = "1"
        env |= {ENV: self.options.realtime} if self.options.realtime else {}
        return env

    def _spawn(self, name: str, args: list[str], command: str = "") -> Child:
        logs = self.options.run_dir / "logs"
        logs.mkdir(parents=True, exist_ok=True)
        log = logs / f"{name}.log"
        argv = [sys.executable, "-m", "manus_stack.cli", command or name, *args]
        env = self._env()
        if forkable(env):
            child = Child(name, argv, log, Forked(argv, env, log, NICE.get(name, 0)))
        else:
            stream = log.open("wb")
            proc = subprocess.Popen(
                argv,
                stdout=stream,
                stderr=subprocess.STDOUT,
                env=env,
                start_new_session=True,
                preexec_fn=(lambda: lower_priority(NICE[name])) if name in NICE else None,  # noqa: PLW1509 (no threads yet)
            )
            child = Child(name, argv, log, proc, stream)
        self.children.append(child)
        return child

    def respawn(self, child: Child, args: list[str] | None = None) -> Child:
        """Start ``child`` again (exited or killed: waited for 5 s at most), with its
        arguments or ``args``, at its place in the start (and stop) order; a fresh log."""
        with contextlib.suppress(subprocess.TimeoutExpired):
            child.proc.wait(timeout=5.0)
        if child.stream is not None:
            child.stream.close()
        index = self.children.index(child)
        self.children.remove(child)
        new = self._spawn(child.name, child.argv[4:] if args is None else args, child.argv[3])
        self.children.remove(new)
        self.children.insert(index, new)
        return new

    def _check(self, child: Child) -> None:
        code = child.proc.poll()
        if code is not None:
            tail = child.log.read_text(errors="replace").strip().splitlines()[-5:]
            raise StackError(
                f"manus {child.name} exited with status {code} (log {child.log}):\n  "
                + "\n  ".join(tail)
            )

    def start(self, timeout: float = 30.0) -> None:
        """Start everything and wait until every service is alive.

        Raises:
            StackError: the port is taken, a process exited, or a service did not come up
                within ``timeout`` [s].
            ConfigError: the guardian's channel given is the bridge's single-reader one.
        """
        opts = self.options
        beside = GuardianCan()
        if opts.can_interface and opts.guardian:  # refused before anything starts
            beside = guardian_can(opts.can_interface, opts.can_channel,
                                  opts.guardian_interface, opts.guardian_channel)  # fmt: skip
            self.notes.append(beside.note)
            if beside.disabled:
                self.disabled[LIVELINESS["guardian"]] = beside.disabled
        opts.run_dir.mkdir(parents=True, exist_ok=True)
        if port_in_use(opts.endpoint):
            raise StackError(
                f"{opts.endpoint} is already in use (another `manus up`?); "
                "choose another with --endpoint"
            )
        # The services' fast collision check: compiled here once if numba's cache is
        # empty (a fresh checkout: ~15 s), so that no service spends its start on it.
        warm_up()
        deadline = time.monotonic() + timeout
        router = self._spawn("router", ["--listen", opts.endpoint])
        while not port_in_use(opts.endpoint):
            self._check(router)
            if time.monotonic() > deadline:
                raise StackError(f"the router did not listen on {opts.endpoint} in time")
            time.sleep(0.05)
        if opts.record:
            self._spawn("record", ["--output", str(opts.recording)])
            self.wait_alive(deadline)
        guardian = opts.guardian
        if opts.can_interface:
            bridge_args = ["--can-interface", opts.can_interface, "--can-channel", opts.can_channel]
            guardian_args = beside.args
        else:
            bridge_args, guardian_args = self._start_sim(deadline)
        plan: list[tuple[str, list[str]]] = [
            ("bridge", bridge_args),
            *([("guardian", guardian_args)] if guardian else []),
            ("planner", []),
            ("controller", []),
            ("sequencer", []),
        ]
        for name, args in plan:
            self._spawn(name, args)
        if opts.record and opts.flight_ring_s > 0:
            ring = ["--ring", f"{opts.flight_ring_s:g}", "--out-dir", str(opts.flight_dir)]
            self._spawn("flight", ring, command="record")
        viewer = self._spawn("view", ["--port", str(opts.view_port)]) if opts.view else None
        self.wait_alive(deadline)
        while viewer is not None and not port_in_use(f"tcp/127.0.0.1:{opts.view_port}"):
            self._check(viewer)  # the viewer holds no token: wait for its port
            if time.monotonic() > deadline:
                raise StackError(f"manus view did not listen in time (log {viewer.log})")
            time.sleep(0.05)

    def _start_sim(self, deadline: float) -> tuple[list[str], list[str]]:
        """Start the simulator (a second node for the guardian): the bridge's and the
        guardian's CAN arguments."""
        opts = self.options
        nodes = ["--nodes", "2"] if opts.guardian else []
        sim_args = ["--device-file", str(opts.device_file), "--objects", opts.objects]
        sim = self._spawn("sim", [*sim_args, *nodes, *opts.sim_args])
        files = [opts.device_file, Path(f"{opts.device_file}.1")][: 2 if opts.guardian else 1]
        while not all(f.exists() for f in files):
            self._check(sim)
            if time.monotonic() > deadline:
                raise StackError(f"the simulator wrote no device file (log {sim.log})")
            time.sleep(0.05)
        self.device = opts.device_file.read_text().strip()
        bridge_args = ["--can-interface", "slcan", "--can-channel", self.device]
        guardian_args = ["--can-interface", "slcan", "--can-channel", files[-1].read_text()]
        return bridge_args, [*guardian_args, "--bridge-channel", self.device]

    def expected(self) -> set[str]:
        """Liveliness names of the started services (but those off on purpose)."""
        names = {LIVELINESS[c.name] for c in self.children if c.name in LIVELINESS}
        return names - set(self.disabled)

    def wait_alive(self, deadline: float) -> None:
        """Wait (until the monotonic ``deadline``) for every started service's token (a
        ``disabled`` one for a service off on purpose)."""
        settings = client_settings(self.options.endpoint, prefix=self.options.prefix)
        with Node("up", settings, liveliness=False) as node:
            while True:
                self._check_all()
                missing = self.expected() - node.alive_services(timeout=0.5)
                if self.disabled:
                    missing |= set(self.disabled) - set(
                        disabled_services(node.session, node.keys, 0.5)
                    )
                if not missing:
                    return
                if time.monotonic() > deadline:
                    raise StackError(
                        f"not alive in time: {', '.join(sorted(missing))} "
                        f"(logs in {self.options.run_dir / 'logs'})"
                    )
                time.sleep(0.1)

    def wait_running(self, timeout: float) -> None:
        """Wait up to ``timeout`` [s] for the bridge's phase ``running``.

        Raises:
            StackError: a process exited, the bridge reached a phase it does not leave by
                itself (stopped, estopped, arm_error, shutdown), or ``timeout`` passed;
                it names the phase and its detail.
        """
        start, since_ns = time.monotonic(), time.time_ns()  # not a restarted one's last
        settings = client_settings(self.options.endpoint, prefix=self.options.prefix)
        with Node("up", settings, liveliness=False) as node:
            state = wait_running(node, start + timeout, self._check_all, since_ns)
        why = not_running(state, time.monotonic() - start)
        if why:
            raise StackError(f"{why} (logs in {self.options.run_dir / 'logs'})")

    def _check_all(self) -> None:
        for child in self.children:
            self._check(child)

    def describe(self) -> list[str]:
        """Where things are, one line each."""
        opts = self.options
        lines = [f"router: {opts.endpoint} (prefix {opts.prefix})"]
        if self.device:
            lines.append(f"simulator: slcan on {self.device}")
        elif opts.can_interface:
            lines.append(f"arm: {opts.can_interface} {opts.can_channel}")
        lines += self.notes
        for c in self.children:
            lines.append(f"{c.name:<10} pid {c.proc.pid:<7} {describe(c.proc.pid):<14} log {c.log}")
        if any(c.name == "record" for c in self.children):
            lines.append(f"recording: {opts.recording}")
        if any(c.name == "flight" for c in self.children):
            lines.append(f"flight recorder: last {opts.flight_ring_s:g} s -> {opts.flight_dir}")
        if any(c.name == "view" for c in self.children):
            lines.append(f"viewer: ws://127.0.0.1:{opts.view_port} (Foxglove: open connection)")
        return lines

    def exited(self) -> list[Child]:
        """Children that have stopped on their own."""
        return [c for c in self.children if c.proc.poll() is not None]

    def stop(self, grace: float = 5.0) -> dict[str, int]:
        """Stop every child, newest first, by pid: SIGINT, then SIGKILL after ``grace`` [s].

        Returns:
            name -> exit status.
        """
        codes: dict[str, int] = {}
        for child in reversed(self.children):
            if child.proc.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.kill(child.proc.pid, signal.SIGINT)
                try:
                    child.proc.wait(timeout=grace)
                except subprocess.TimeoutExpired:
                    with contextlib.suppress(ProcessLookupError):
                        os.kill(child.proc.pid, signal.SIGKILL)
                    child.proc.wait(timeout=grace)
            codes[child.name] = int(child.proc.returncode or 0)
            if child.stream is not None:
                child.stream.close()
        self.children.clear()
        return codes

    def __enter__(self) -> LocalStack:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
