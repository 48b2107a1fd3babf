"""The verdict of a finished soak: every round judged on the simulator's truth and the
events the soak watched, and the recordings' completeness (:mod:`manus_stack.chaos.judge`
holds the invariants; this module applies them to what :class:`~manus_stack.chaos.soak.Soak`
did). The figures are the bench's JSON (``manus bench chaos``).
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from manus_stack.chaos import judge
from manus_stack.chaos.schedule import FaultKind, Outcome, Round, TaskKind
from manus_stack.chaos.watch import Watcher, digest
from schemas import endpoints as ep
from schemas.sequencing import TaskEvent
from services.recorder.reading import Recording, decode
from services.recorder.recover import recover
from services.sequencer.config import SequencerConfig
from services.simulator.truth_log import TruthLine, read_truth_log

SERVICES = {s.value for s in ep.Service}
"""Owners of numbered streams (``estop``, anyone's, is not one stream)."""


@dataclass
class Life:
    """One recorder process: its file, its pid and when it was alive [wall ns] (end 0: to
    the end): from its ``where`` token's appearance (it subscribes before it declares it)."""

    path: Path
    pid: int
    start_ns: int
    end_ns: int = 0
    killed: bool = False
    pauses: list[tuple[int, int]] = field(default_factory=list)


@dataclass
class Done:
    """What happened in one round (wall ns; 0: did not happen)."""

    round: Round
    task_id: str = ""
    refused: str = ""
    fault_ns: int = 0
    fault_sim_ns: int = 0
    step: str = ""
    recovery_ns: int = 0
    ready_ns: int = 0
    next_submit_ns: int = 0
    note: str = ""


@dataclass
class Verdict:
    """Judges what a soak did (see the module docstring).

    Attributes:
        w: the soak's watcher (what it saw on the bus).
        done: the rounds, in order.
        lives: the recorder processes.
        t0: when the soak started [wall ns].
        truth_log: the simulator's truth log (its truth through router restarts).
        seed: the schedule's seed.
        minutes: the soak's length [min].
        faults: the fault kinds drawn from.
        tasks: the tasks run in turn.
        run_dir: logs, recordings.
        say: progress lines.
        unrecorded: numbered samples missing from the recordings, per key (set by
            :meth:`figures`).
    """

    w: Watcher
    done: list[Done]
    lives: list[Life]
    t0: int
    truth_log: Path
    seed: int
    minutes: float
    faults: tuple[FaultKind, ...]
    tasks: tuple[TaskKind, ...]
    run_dir: Path
    say: Callable[[str], None]
    unrecorded: dict[str, int] = field(default_factory=dict)

    def figures(self) -> dict[str, Any]:
        """Judge every round and the recordings; the bench's JSON figures."""
        w = self.w
        offset = w.sim_offset_ns()
        if self.truth_log.exists():
            truth = read_truth_log(self.truth_log)
        else:  # an older simulator: the bus's truth (not through a router restart)
            truth = [judge.from_truth(t) for t in w.truth_since(0)]
        violations: list[dict[str, Any]] = []
        stops: dict[str, list[float]] = {}
        rounds: list[dict[str, Any]] = []

        def sim(wall: int) -> int:
            return wall - offset

        def violated(done: Done, what: str, after: str = "") -> None:
            violation = {
                "round": done.round.index,
                "fault": done.round.fault.name,
                "task": done.round.task.name,
                "step": done.step,
                "t_s": round((done.fault_ns - self.t0) / 1e9, 2),
                "what": what,
            }
            if after:  # the aftermath of the previous round's fault
                violation["after"] = after
            violations.append(violation)

        for done in self.done:
            fault = done.round.fault
            row: dict[str, Any] = {
                "round": done.round.index,
                "task": done.round.task.name,
                "step": done.step,
                "fault": fault.name,
            }
            rounds.append(row)
            if done.refused:
                row["refused"] = done.refused
                violated(done, f"task refused after the recovery: {done.refused}")
                continue
            if done.note:
                row["note"] = done.note
            fault_sim = done.fault_sim_ns or sim(done.fault_ns)
            finals = judge.final_events(w.events_of(done.task_id))
            early = [e for e in finals if e.stamp_ns < done.fault_ns]
            if early and early[0].event != "succeeded":
                before = self.done.index(done) - 1
                after = self.done[before].round.fault.name if before >= 0 else ""
                what = f"the task {early[0].event} before its fault: {early[0].reason!r}"
                violated(done, what, after)
            elif early:
                row["note"] = "the task succeeded before the fault came (an idle arm was hit)"
            if fault.stops and not (early and early[0].event != "succeeded"):
                self._judge_stop(done, truth, fault_sim, sim, violated, stops, row)
            row["final"] = [f"{e.event}: {e.reason}" for e in finals]
            if w.recovered(done.task_id):
                row["final_from_history"] = True
            for what in self._judge_final(fault, finals, bool(early)):
                violated(done, what)
        rec = self._completeness()
        injected = [d for d in self.done if d.fault_ns]
        kinds = sorted({d.round.fault.name for d in injected})
        return {
            "seed": self.seed,
            "minutes": self.minutes,
            "fault_kinds": [f.name for f in self.faults],
            "tasks": [t.name for t in self.tasks],
            "faults_injected": len(injected),
            "faults_by_kind": {k: sum(d.round.fault.name == k for d in injected) for k in kinds},
            "tasks_run": sum(1 for d in self.done if d.task_id),
            "tasks_succeeded": sum(
                1
                for d in self.done
                if any(e.event == "succeeded" for e in judge.final_events(w.events_of(d.task_id)))
            ),
            "invariant_violations": violations,
            "worst_stop_ms": {k: round(max(v), 1) for k, v in sorted(stops.items())},
            "recorder_lost_messages": rec.lost,
            "recorder_expected_messages": rec.expected,
            "recorder_lost_by_key": rec.lost_by_key,
            "unrecorded_by_seq": self.unrecorded,
            "recordings": [str(life.path) for life in self.lives],
            "rounds": rounds,
            "run_dir": str(self.run_dir),
            "load_avg_1min": round(os.getloadavg()[0], 2),
        }

    @staticmethod
    def _judge_final(fault: FaultKind, finals: list[TaskEvent], early: bool) -> list[str]:
        """What is wrong with the task's final events (one, naming the fault)."""
        wrong = []
        if fault.event and len(finals) != 1:
            wrong.append(f"{len(finals)} final events (one expected)")
        elif not fault.event and len(finals) > 1:
            wrong.append(f"{len(finals)} final events (at most one expected)")
        for e in finals[:1] if not early else []:
            want = fault.outcome
            if want is not Outcome.ANY and e.event != want.value:
                wrong.append(f"task {e.event} ({e.reason!r}), expected {want.value}")
            elif e.event == "failed" and not judge.names_fault(e.reason, fault.reason):
                wrong.append(f"the reason {e.reason!r} names none of {list(fault.reason)}")
        return wrong

    def _judge_stop(
        self,
        done: Done,
        truth: list[TruthLine],
        fault_sim: int,
        sim: Callable[[int], int],
        violated: Callable[[Done, str], None],
        stops: dict[str, list[float]],
        row: dict[str, Any],
    ) -> None:
        """The arm stopped in time after the fault and nothing moved by itself."""
        fault = done.round.fault
        recovery = sim(done.recovery_ns)
        if fault.resumes and fault.sim.get("duration_ms"):  # the fault ends by itself
            recovery = min(recovery, fault_sim + round(fault.sim["duration_ms"] * 1e6))
        s = judge.stop_after(truth, fault_sim, recovery, sim(done.next_submit_ns))
        stop_ms = None if s.stop_ns is None else (s.stop_ns - fault_sim) / 1e6
        row["stop_ms"] = None if stop_ms is None else round(stop_ms, 1)
        if stop_ms is not None:
            stops.setdefault(fault.name, []).append(stop_ms)
        if s.stop_ns is None or s.stop_ns > recovery:
            at_rest = "" if stop_ms is None else f" (at rest {stop_ms:.0f} ms after the fault)"
            violated(done, f"the arm kept moving on a stale command until the recovery{at_rest}")
            return
        limit_ns = judge.stop_limit_ns(self._deadman_s(done.step) if fault.deadman else None)
        if s.stop_ns - fault_sim > limit_ns:
            limit = limit_ns / 1e6
            violated(done, f"at rest only {stop_ms:.0f} ms after the fault (limit {limit:.0f} ms)")
        if s.resumed_ns is not None:
            after = (s.resumed_ns - fault_sim) / 1e6
            violated(done, f"moved by itself {after:.0f} ms after the fault, before the recovery")
        if fault.resumes:
            return
        moved = judge.largest_motion(truth, recovery, sim(done.ready_ns))
        if moved > judge.RECOVERY_TOL:
            violated(done, f"moved {np.degrees(moved):.2f} deg during the recovery")
        if judge.first_motion(truth, sim(done.ready_ns), sim(done.next_submit_ns)) is not None:
            violated(done, "moved by itself after the recovery, before the next task")

    @staticmethod
    def _deadman_s(step: str) -> float:
        """The heartbeat timeout of the step the fault hit [s] (the sequencer's defaults,
        which ``manus up`` runs)."""
        cfg = SequencerConfig()
        return cfg.fold_heartbeat_timeout_s if step.startswith("fold") else cfg.heartbeat_timeout_s

    def _token_gaps(self, service: str, pid: int) -> list[tuple[int, int]]:
        """When the soak's node saw the ``where`` token of ``service``'s process ``pid``
        gone, [vanished, back] [wall ns] (a router restart cuts every token, a stopped
        process loses its link once its lease expires: the recorder is not on the bus)."""
        with self.w.seen.lock:
            where = list(self.w.seen.where)
        return judge.token_gaps([(t, up) for s, p, up, t in where if (s, p) == (service, pid)])

    def _completeness(self) -> judge.Completeness:
        recorded: set[tuple[str, bytes]] = set()
        numbered: list[tuple[str, int, int]] = []
        process_windows: list[tuple[int, int]] = []
        windows: list[tuple[int, int]] = []
        for life in self.lives:
            path = life.path
            if life.killed:
                fixed = path.with_suffix(".recovered.mcap")
                try:
                    recover(path, fixed)
                    path = fixed
                except Exception as exc:  # judged as lost, not a crash of the soak
                    self.say(f"cannot recover {path}: {exc}")
                    continue
            windows += _cut(
                life.start_ns, life.end_ns, [*life.pauses, *self._token_gaps("recorder", life.pid)]
            )
            process_windows += _cut(life.start_ns, life.end_ns, life.pauses)
            with contextlib.suppress(Exception):
                for rec in Recording(path).messages():
                    recorded.add((rec.key, digest(rec.payload)))
                    endpoint = ep.TABLE.get(rec.suffix)
                    if endpoint is not None and endpoint.owner in SERVICES:
                        with contextlib.suppress(Exception):
                            seq = getattr(decode(rec), "seq", None)
                            if isinstance(seq, int):
                                numbered.append((rec.key, seq, rec.log_ns))
        with self.w.seen.lock:
            samples = list(self.w.seen.samples)
        gaps = judge.seq_gaps(numbered, process_windows)
        self.unrecorded = {k.removeprefix("chaos/"): n for k, n in gaps.items()}
        return judge.completeness(samples, windows, recorded, "chaos")


def _cut(start: int, end: int, cuts: list[tuple[int, int]]) -> list[tuple[int, int]]:
    """[start, end] without the ``cuts`` ([a, b] each), as windows."""
    windows = []
    for a, b in sorted(cuts):
        if a > start:
            windows.append((start, min(a, end)))
        start = max(start, b)
    if start < end:
        windows.append((start, end))
    return windows
