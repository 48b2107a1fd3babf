"""The soak itself: ``manus up``'s stack, tasks back to back, one fault per task.

Each round (:class:`~manus_stack.chaos.schedule.Round`): wait until the stack is ready
(every started service alive, the bridge ``running``), submit the task through the
sequencer as a supervisor would, wait until its last step runs and the arm moves, wait
the round's delay, inject the fault, hold it, make the documented recovery (start again
what was killed, SIGCONT what was stopped, clear the simulator's faults, release an
e-stop, ``clear`` the bridge), wait for the task's end, and go on. Every instant is kept
(wall clock, converted to the simulator's clock through its truth samples) for the judge;
:meth:`Soak.figures` judges once the stack is down and the recordings are closed
(:mod:`manus_stack.chaos.verdict`).
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import time
from pathlib import Path
from typing import IO, Any

from manus.node import QueryError
from manus.session import client_settings
from manus_stack.chaos import judge
from manus_stack.chaos.schedule import (
    FAULTS,
    TASKS,
    Action,
    FaultKind,
    Outcome,
    Round,
    TaskKind,
    draw,
)
from manus_stack.chaos.verdict import Done, Life, Verdict
from manus_stack.chaos.watch import Watcher
from manus_stack.ports import free_port, port_in_use
from manus_stack.up import Child, LocalStack, StackOptions
from schemas import endpoints as ep
from schemas.commands import ArmCommand, ArmCommandReply, EStop
from schemas.sequencing import SubmitReply, TaskControl, TaskStatus
from schemas.simfault import SimFault, SimFaultReply

LATCHED = ("arm_error", "stopped", "estopped")
"""Bridge phases that wait for ``clear``."""


class Soak:
    """Runs the soak (see the module docstring).

    Args:
        run_dir: logs, recordings.
        minutes: no new round starts after this long [min].
        seed: the schedule's seed.
        out: progress lines (None: nowhere).
        faults: the fault kinds drawn from (a targeted soak: a few of them).
        tasks: the tasks run in turn.
    """

    def __init__(
        self,
        run_dir: Path,
        minutes: float,
        seed: int,
        out: IO[str] | None,
        faults: tuple[FaultKind, ...] = FAULTS,
        tasks: tuple[TaskKind, ...] = TASKS,
    ) -> None:
        self.run_dir = run_dir
        self.minutes = minutes
        self.seed = seed
        self.out = out
        self.faults = faults
        self.tasks = tasks
        endpoint = f"tcp/127.0.0.1:{free_port()}"
        self.truth_log = run_dir / "truth.txt"
        self.options = StackOptions(
            run_dir=run_dir,
            endpoint=endpoint,
            prefix="chaos",
            sim_args=["--truth-log", str(self.truth_log)],
        )
        self.stack = LocalStack(self.options)
        self.watcher: Watcher | None = None
        self.lives: list[Life] = []
        self.done: list[Done] = []
        self.t0 = 0
        self.unrecorded: dict[str, int] = {}
        self._since_ns = 0
        """The newest recovery [wall ns]: the stack is ready on a bridge state after it."""

    # -- plumbing ---------------------------------------------------------------------------

    def _say(self, text: str) -> None:
        if self.out is not None:
            self.out.write(f"chaos {(time.time_ns() - self.t0) / 1e9:7.1f} s  {text}\n")
            self.out.flush()

    @property
    def w(self) -> Watcher:
        assert self.watcher is not None
        return self.watcher

    def _child(self, name: str) -> Child:
        return [c for c in self.stack.children if c.name == name][-1]

    def _query(self, suffix: str, request: Any, reply: type[Any], timeout: float = 3.0) -> Any:
        node = self.w.node
        return node.query(node.keys(suffix), request, reply, timeout=timeout)

    def _wait(self, cond: Any, timeout: float, step: float = 0.05) -> bool:
        end = time.monotonic() + timeout
        while not cond():
            if time.monotonic() > end:
                return False
            time.sleep(step)
        return True

    def _moving(self) -> bool:
        truth = [judge.from_truth(t) for t in self.w.truth_since(0)[-3:]]
        return len(truth) == 3 and not judge.quiet(truth[0], truth[2])

    def _ready(self) -> bool:
        expected = self.stack.expected()
        alive = self.w.node.alive_services(timeout=0.3)
        return expected <= alive and self.w.phase(self._since_ns) == "running"

    # -- the run ------------------------------------------------------------------------

    def start(self) -> None:
        """Bring the stack up (as ``manus up`` does) and the soak's node."""
        self.t0 = time.time_ns()
        self.stack.start(timeout=90.0)
        self.lives.append(Life(self.options.recording, self._child("record").proc.pid, self.t0))
        self.watcher = Watcher(client_settings(self.options.endpoint, prefix="chaos"))
        if not self._wait(lambda: self.w.phase() == "running", 60.0):
            raise RuntimeError("the bridge did not reach phase running in 60 s")
        self._say(f"stack up: {self.options.endpoint}, logs in {self.run_dir / 'logs'}")

    def run(self) -> None:
        """Rounds until the time is up."""
        end = time.monotonic() + self.minutes * 60.0
        for rnd in draw(self.seed, 10_000, self.faults, self.tasks):
            if time.monotonic() >= end:
                break
            done = Done(rnd)
            self.done.append(done)
            self._round(done)

    def _round(self, done: Done) -> None:
        rnd = done.round
        if not self._wait(self._ready, 45.0, 0.1):
            done.note = "stack not ready after the previous recovery"
            self._say(f"round {rnd.index}: {done.note}")
        time.sleep(0.3)  # a moment at rest, judged: nothing moves by itself
        if len(self.done) > 1:
            self.done[-2].next_submit_ns = time.time_ns()
        reply = self._submit(rnd)
        if reply is None or not reply.accepted:
            done.refused = "; ".join(reply.errors) if reply is not None else "no reply"
            self._say(f"round {rnd.index}: {rnd.task.name} refused: {done.refused}")
            return
        done.task_id = reply.task_id
        if not self._wait(lambda: self._last_step_moving(done), 60.0):
            done.note = "the task's last step never moved the arm: fault injected anyway"
        time.sleep(rnd.delay_s)
        started = [e for e in self.w.events_of(done.task_id) if e.event == "step_started"]
        done.step = started[-1].kind if started else ""
        self._say(f"round {rnd.index}: {rnd.task.name} ({done.step}) + {rnd.fault.name}")
        self._inject(done, rnd.fault)
        self._finish(done, rnd.fault)

    def _submit(self, rnd: Round) -> SubmitReply | None:
        task = rnd.task.task()
        reply: SubmitReply | None = None
        end = time.monotonic() + 20.0
        while time.monotonic() < end:
            try:
                reply = self._query(ep.SUBMIT, task, SubmitReply, timeout=20.0)
            except QueryError as exc:
                reply = SubmitReply(accepted=False, task_id="", errors=[str(exc)])
            if reply.accepted:
                return reply
            time.sleep(0.5)
        return reply

    def _last_step_moving(self, done: Done) -> bool:
        events = self.w.events_of(done.task_id)
        if judge.final_events(events):
            return True
        last = [e for e in events if e.event == "step_started" and e.step == e.total - 1]
        return bool(last) and self._moving()

    # -- faults and recoveries -------------------------------------------------------------

    def _inject(self, done: Done, fault: FaultKind) -> None:
        done.fault_ns = time.time_ns()
        if fault.action in (Action.SIGKILL, Action.SIGSTOP):
            child = self._child(fault.target)
            sig = signal.SIGKILL if fault.action is Action.SIGKILL else signal.SIGSTOP
            os.kill(child.proc.pid, sig)
            if fault.target == "record":
                life = self.lives[-1]
                if fault.action is Action.SIGKILL:
                    life.end_ns, life.killed = done.fault_ns, True
            time.sleep(fault.hold_s)
            done.recovery_ns = time.time_ns()
            if fault.action is Action.SIGKILL:
                self._restart(child)
            else:
                os.kill(child.proc.pid, signal.SIGCONT)
                if fault.target == "record":
                    back = self._recorder_back(child.proc.pid)
                    self.lives[-1].pauses.append((done.fault_ns, back))
        elif fault.action is Action.SIM:
            try:
                reply = self._query(
                    ep.SIM_FAULT, SimFault(**fault.sim, source="chaos"), SimFaultReply
                )
                done.fault_sim_ns = reply.start_ns
            except QueryError as exc:
                done.note = f"sim/fault: {exc}"
            time.sleep(max(fault.hold_s, fault.sim.get("duration_ms", 0.0) / 1e3))
            done.recovery_ns = time.time_ns()
            with contextlib.suppress(QueryError):
                self._query(ep.SIM_FAULT, SimFault(kind="clear", source="chaos"), SimFaultReply)
        elif fault.action is Action.ESTOP:
            pub = self.w.node.publisher(self.w.node.keys(ep.ESTOP))
            pub.put(
                EStop(
                    stamp_ns=time.time_ns(),
                    seq=2 * done.round.index,
                    engaged=True,
                    source="chaos",
                    reason="chaos soak",
                )
            )
            time.sleep(fault.hold_s)
            done.recovery_ns = time.time_ns()
            pub.put(
                EStop(
                    stamp_ns=time.time_ns(),
                    seq=2 * done.round.index + 1,
                    engaged=False,
                    source="chaos",
                )
            )
        else:
            router = self._child("router")
            os.kill(router.proc.pid, signal.SIGKILL)
            time.sleep(fault.hold_s)
            done.recovery_ns = time.time_ns()
            self.stack.respawn(router)
            self._wait(lambda: port_in_use(self.options.endpoint), 10.0)
        # ready means a bridge state from after the recovery: a restarted bridge's first
        # states come seconds later, and the last one seen is the dead bridge's `running`
        self._since_ns = done.recovery_ns
        self._clear_latched()

    def _restart(self, child: Child) -> None:
        if child.name != "record":
            self.stack.respawn(child)
            return
        path = self.run_dir / f"recording-{len(self.lives)}.mcap"
        started = time.time_ns()
        new = self.stack.respawn(child, ["--output", str(path)])
        back = self._recorder_back(new.proc.pid)
        self.lives.append(Life(path, new.proc.pid, back))
        self._say(f"recorder pid {new.proc.pid} on the bus {(back - started) / 1e9:.2f} s after")

    def _recorder_back(self, pid: int) -> int:
        """Wait (10 s at most) for the recorder process ``pid`` to be on the bus (its
        ``where`` token: ``alive/recorder`` is the flight recorder's too, which never
        left); when it is back [wall ns]."""
        self._wait(lambda: self.w.on_bus("recorder", pid), 10.0, 0.01)
        return time.time_ns()

    def _clear_latched(self) -> None:
        """The documented recovery of a latched bridge: ``clear`` until it runs again."""
        end = time.monotonic() + 15.0
        while time.monotonic() < end:
            time.sleep(0.2)
            if self.w.phase(self._since_ns) in LATCHED:
                with contextlib.suppress(QueryError):
                    self._query(
                        ep.BRIDGE_COMMAND,
                        ArmCommand(action="clear", source="chaos"),
                        ArmCommandReply,
                    )
            elif self.w.phase(self._since_ns) == "running":
                return

    def _finish(self, done: Done, fault: FaultKind) -> None:
        """Wait for the task's end (a task that should fail gets 10 s, one that should
        succeed 60 s), then cancel it if it still runs."""
        wait = 60.0 if fault.outcome is Outcome.SUCCEEDED else 10.0
        if fault.event:
            ended = self._wait(lambda: judge.final_events(self.w.events_of(done.task_id)), wait)
            if not ended:
                with contextlib.suppress(QueryError):
                    self._query(ep.TASK_CONTROL, TaskControl(action="cancel"), TaskStatus)
                self._wait(lambda: judge.final_events(self.w.events_of(done.task_id)), 5.0)
        self._wait(self._ready, 45.0, 0.1)
        done.ready_ns = time.time_ns()

    def stop(self) -> None:
        """Stop the soak's node and the stack (the recorder closes its file)."""
        if self.lives and self.lives[-1].end_ns == 0:
            self.lives[-1].end_ns = time.time_ns()
        if self.done and self.done[-1].next_submit_ns == 0:
            self.done[-1].next_submit_ns = time.time_ns()
        if self.watcher is not None:
            self.watcher.close()
        self.stack.stop(grace=10.0)

    # -- the figures ------------------------------------------------------------------------

    def figures(self) -> dict[str, Any]:
        """Judge every round and the recordings (:mod:`manus_stack.chaos.verdict`); the
        bench's JSON figures."""
        verdict = Verdict(
            self.w,
            self.done,
            self.lives,
            self.t0,
            self.truth_log,
            self.seed,
            self.minutes,
            self.faults,
            self.tasks,
            self.run_dir,
            self._say,
        )
        figures = verdict.figures()
        self.unrecorded = verdict.unrecorded
        return figures


def run_soak(
    run_dir: Path,
    minutes: float,
    seed: int,
    out: IO[str] | None,
    faults: tuple[FaultKind, ...] = FAULTS,
    tasks: tuple[TaskKind, ...] = TASKS,
) -> dict[str, Any]:
    """Run one soak (of ``faults`` on ``tasks``: by default every one) and return its
    figures (the stack is always stopped)."""
    soak = Soak(run_dir, minutes, seed, out, faults, tasks)
    try:
        soak.start()
        soak.run()
    finally:
        soak.stop()
    figures = soak.figures()
    (run_dir / "chaos.json").write_text(json.dumps(figures, indent=2) + "\n")
    return figures
