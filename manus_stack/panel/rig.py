"""The whole stack on the simulator with ``manus panel`` on it, and the simulator's truth:
what the panel's screenshots (:mod:`manus_stack.panel.shots`) and its browser tests
(``tests/test_panel_browser.py``) run against.

The stack is ``manus up``'s (:class:`~manus_stack.up.LocalStack`: its own loopback router,
the simulator, bridge, planner, controller and sequencer; no recorder), the panel a
``manus panel`` process of its own on a free port, and the truth (``sim/truth``,
:class:`~schemas.state.SimTruth`) is followed by a node of this process: what the arm
really does is judged there, never on what the stack or the page says.
"""

from __future__ import annotations

import itertools
import math
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING

from manus.node import Node
from manus.session import client_settings
from manus_stack.panel.touch import Fingers
from manus_stack.ports import free_port, port_in_use
from manus_stack.up import LocalStack, StackError, StackOptions
from schemas import endpoints as ep
from schemas.sequencing import TaskEvent, TaskEventKind
from schemas.state import SimTruth
from services.controller.jog_config import JogConfig
from services.simulator.config import SimConfig

if TYPE_CHECKING:
    from playwright.sync_api import Page

STILL_RAD_S = math.radians(0.5)
"""A joint is still below this true speed (0.5 deg/s, as ``manus bench jog`` judges)."""
DEADMAN_MS = JogConfig().timeout_ms
"""The controller's jog deadman [ms]."""
CYCLE_MS = 60.0
"""The arm's cycle: the longest wait for the next sync, and the truth's period [ms]."""
ACTS_MS = 20.0
"""From a sync's reply to its motion (docs/architecture.md, Time) [ms]."""
TAU_MS = SimConfig().transient_tau_ms
"""The drives' speed lag [ms]."""


def floor_ms(speed: float) -> float:
    """The protocol's floor: the longest any PC program needs to bring a joint moving at
    ``speed`` [rad/s] to rest (docs/jog.md, Measured): the wait for the next sync, the
    reply acting 20 ms later, and the drives' lag down to 0.5 deg/s (a motor may turn up
    to twice a DH joint's speed: the joint map couples motors 2 and 3)."""
    return CYCLE_MS + ACTS_MS + TAU_MS * math.log(max(1.0, 2 * speed / STILL_RAD_S))


def stop_bound_ms(speed: float) -> float:
    """What a stop may take as the truth shows it (docs/panel.md, Tests and screenshots):
    the deadman, the floor, and one period of the truth (a stop is seen at the first truth
    published after it)."""
    return DEADMAN_MS + floor_ms(speed) + CYCLE_MS


def recover(page: Page) -> None:
    """What a helper does when a fault left the arm held stopped (the bridge's phase
    ``stopped``, "The arm stopped itself after a fault"): STOP, then Release stop on the
    panel's ``page`` (the bridge re-enters joint mode when the e-stop is released)."""
    page.click("#stop")
    page.wait_for_selector("#release-stop", state="visible")
    page.click("#release-stop")
    page.wait_for_selector("#release-stop", state="hidden")
    time.sleep(1.0)  # the bridge back in running


class PanelRig:
    """A stack on the simulator, ``manus panel`` on it, and the truth.

    Args:
        run_dir: logs of every process (``logs/<name>.log``).
        prefix: the stack's key prefix.
        panel_args: more options of ``manus panel``.
        objects: the simulator's objects (``manus sim --objects``).
        sim_args: more options of ``manus sim`` (``--config FILE``: a moving mouth).
    """

    def __init__(
        self,
        run_dir: Path,
        prefix: str = "panel",
        panel_args: tuple[str, ...] = (),
        objects: str = "default",
        sim_args: tuple[str, ...] = (),
    ) -> None:
        self.run_dir = run_dir
        self.stack = LocalStack(
            StackOptions(
                run_dir=run_dir,
                endpoint=f"tcp/127.0.0.1:{free_port()}",
                prefix=prefix,
                record=False,
                guardian=False,
                flight_ring_s=0.0,
                objects=objects,
                sim_args=list(sim_args),
            )
        )
        self.port = free_port()
        self.url = f"http://127.0.0.1:{self.port}/"
        self._panel_args = panel_args
        self._panel: subprocess.Popen[bytes] | None = None
        self._node: Node | None = None
        self._lock = threading.Lock()
        self.truths: list[tuple[int, SimTruth]] = []
        """Every truth received: (receive time [ns, wall clock], truth)."""
        self.events: list[tuple[int, TaskEvent]] = []
        """The sequencer's task events, as this process received them: (receive time [ns,
        wall clock], event), the newest 200."""

    def start(self, timeout: float = 90.0) -> None:
        """Start the stack, then the panel; wait until the panel listens.

        Raises:
            StackError: something did not come up (naming its log).
        """
        opts = self.stack.options
        self.stack.start(timeout)
        self._node = Node("panel_rig", client_settings(opts.endpoint, prefix=opts.prefix),
                          liveliness=False)  # fmt: skip
        self._node.subscribe(self._node.keys(ep.SIM_TRUTH), SimTruth, self._truth, locked=False)
        self._node.subscribe(self._node.keys(ep.EVENTS), TaskEvent, self._event, locked=False)
        log = (self.run_dir / "logs" / "panel.log").open("wb")
        argv = [sys.executable, "-m", "manus_stack.cli", "panel", "--port", str(self.port),
                "--connect", opts.endpoint, "--prefix", opts.prefix, *self._panel_args]  # fmt: skip
        env = {**os.environ, "PYTHONUNBUFFERED": "1"}
        env.pop("MANUS_ZENOH_CONFIG", None)
        self._panel = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT, env=env,
                                       start_new_session=True)  # fmt: skip
        log.close()
        deadline = time.monotonic() + 30.0
        while not port_in_use(f"tcp/127.0.0.1:{self.port}"):
            if self._panel.poll() is not None or time.monotonic() > deadline:
                raise StackError(f"manus panel did not listen (log {self.run_dir}/logs/panel.log)")
            time.sleep(0.05)

    def _truth(self, truth: SimTruth, rx_ns: int) -> None:
        with self._lock:
            self.truths.append((rx_ns, truth))
            del self.truths[:-2000]  # two minutes of cycles

    def _event(self, event: TaskEvent, rx_ns: int) -> None:
        with self._lock:
            self.events.append((rx_ns, event))
            del self.events[:-200]

    def story(self, last: int = 12) -> str:
        """The newest task events and the truth's contacts (each pair, and the step that ran
        when the count last grew), for a failed test's message."""
        with self._lock:
            heard = [(rx, e) for rx, e in self.events if e.event != TaskEventKind.STEP_PROGRESS]
            truths = list(self.truths)
        lines = [
            f"  #{e.seq} {e.task_id} {e.event} step {e.step}/{e.total} {e.kind}"
            + (f": {e.reason}" if e.reason else "")
            for _, e in heard[-last:]
        ]
        if truths:
            truth = truths[-1][1]
            lines.append(f"  truth: {truth.contacts} contact ticks, last {truth.contact!r}")
            lines += [
                f"  contact {c.first}/{c.second} ({c.cls}): {c.ticks} ticks from sim time "
                f"{c.since_ns / 1e9:.2f} s, {c.depth * 1e3:.2f} mm deep"
                for c in truth.object_contacts
            ]
            pairs = itertools.pairwise(truths)
            grew = [rx for (_, a), (rx, b) in pairs if b.contacts > a.contacts]
            if grew:
                began = TaskEventKind.STEP_STARTED
                started = [e for rx, e in heard if rx <= grew[-1] and e.event == began]
                step = f"step {started[-1].step} ({started[-1].kind})" if started else "no step"
                lines.append(f"  the count last grew during {step} of the task then")
        return "the newest task events:\n" + "\n".join(lines)

    def latest(self) -> SimTruth | None:
        """The newest truth."""
        with self._lock:
            return self.truths[-1][1] if self.truths else None

    def speed(self) -> float:
        """The newest true speed of the fastest joint [rad/s] (0: none yet)."""
        truth = self.latest()
        return max((abs(v) for v in truth.qd_true), default=0.0) if truth else 0.0

    def wait_moving(self, timeout: float = 10.0) -> int:
        """Wait until some joint truly moves; the receive time of that truth [ns].

        Raises:
            TimeoutError: nothing moved within ``timeout`` [s].
        """
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self._lock:
                last = self.truths[-1] if self.truths else None
            if last is not None and max(map(abs, last[1].qd_true), default=0.0) > STILL_RAD_S:
                return last[0]
            time.sleep(0.01)
        raise TimeoutError(f"the arm did not move within {timeout} s")

    def hold_until_moving(self, fingers: Fingers, pad: str, tries: int = 5) -> None:
        """Hold the pad button ``pad`` with finger 1 until the arm truly moves and is up to
        speed (a jog that an earlier stop left waiting for a release needs the finger
        lifted and pressed again, as a person would).

        Raises:
            TimeoutError: ``tries`` presses did not move the arm.
        """
        for _ in range(tries):
            fingers.press(1, f"#pad-{pad}")
            try:
                self.wait_moving(timeout=2.0)
                time.sleep(0.3)
                return
            except TimeoutError:
                fingers.lift(1)
                time.sleep(0.5)
        raise TimeoutError(f"holding {pad} never moved the arm ({tries} presses)")

    def still_since(self, since_ns: int, timeout: float = 3.0) -> tuple[int, float]:
        """Wait for the first truth sampled after ``since_ns`` with every joint still.

        A truth is placed in time by its own stamp (the simulator's clock), moved onto this
        process's clock by the smallest (receive time - stamp) seen: the time it was
        sampled, not when it arrived (a test process short of CPU receives it late).

        Returns:
            (when it was sampled [ns, this process's wall clock], the fastest true joint
            speed of the last truth sampled before ``since_ns`` [rad/s]).

        Raises:
            TimeoutError: the arm still moved ``timeout`` [s] later.
        """
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self._lock:
                offset = min(rx - t.stamp_ns for rx, t in self.truths)
                placed = [(t.stamp_ns + offset, t) for _, t in self.truths]
            before = [t for at, t in placed if at < since_ns][-1:]
            for at, truth in placed:
                if at >= since_ns and max(map(abs, truth.qd_true), default=0.0) < STILL_RAD_S:
                    moving = max(map(abs, before[0].qd_true), default=0.0) if before else 0.0
                    return at, moving
            time.sleep(0.01)
        raise TimeoutError(f"the arm still moved {timeout} s after the stop")

    def stop(self) -> None:
        """Stop the panel, the truth's node and the stack (every process by its pid)."""
        if self._panel is not None and self._panel.poll() is None:
            os.kill(self._panel.pid, signal.SIGINT)
            try:
                self._panel.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                os.kill(self._panel.pid, signal.SIGKILL)
                self._panel.wait(timeout=5.0)
        if self._node is not None:
            self._node.close()
        self.stack.stop()

    def __enter__(self) -> PanelRig:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
