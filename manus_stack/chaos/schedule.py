"""What the soak does, as data: the faults (:data:`FAULTS`), the tasks (:data:`TASKS`),
and the seeded draw of one (task, fault, delay) per round (:func:`draw`).

A fault is injected while a task runs, ``delay_s`` after the arm starts moving; each
fault kind says what it does (``action``: a signal to a process of ``manus up``, a fault
switched on in the simulator through ``sim/fault``, an e-stop, a router restart), how
long it holds before the recovery, and what the stack must do about it: stop the arm
(``stops``: judged on the truth), end the task (``outcome``) with a reason naming the
fault (``reason``: any of these words). The recovery follows from the action: a killed
process is started again, a stopped one continued, an arm error cleared, an e-stop
released. New faults (the guardian's) and tasks (jogs) are new rows here.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import StrEnum
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from manus.errors import ConfigError
from manus.viapoints import load_path
from schemas.sequencing import Task, TaskStep

ROOT = Path(__file__).resolve().parent.parent.parent
PATHS = ROOT / "paths"


class Action(StrEnum):
    """How a fault is made."""

    SIGKILL = "sigkill"
    """kill the target process outright (recovery: start it again)"""
    SIGSTOP = "sigstop"
    """freeze the target process for ``hold_s`` (recovery: SIGCONT)"""
    SIM = "sim"
    """switch a fault on in the simulator (``sim/fault``; recovery: ``clear``)"""
    ESTOP = "estop"
    """an engaged e-stop for ``hold_s`` (recovery: released, then ``clear``)"""
    ROUTER = "router"
    """the Zenoh router killed and started again ``hold_s`` later: every link cut"""


class Outcome(StrEnum):
    """How the task hit by the fault must end."""

    FAILED = "failed"
    SUCCEEDED = "succeeded"
    ANY = "any"


@dataclass(frozen=True)
class FaultKind:
    """One row of the fault table.

    Attributes:
        name: the kind's name in the figures (``bridge_sigkill``).
        action: how it is made.
        target: the ``manus`` subcommand hit (signals), or '' for the others.
        sim: the ``SimFault`` fields (action ``sim``).
        hold_s: how long the fault lasts before the recovery starts [s].
        stops: the arm must stop within two cycles and stay stopped until the next task.
        outcome: how the task must end.
        reason: words of which the final event's reason must contain one (lower case).
        resumes: the task may go on once the fault is over (a transient CAN fault costs
            a short stop, not the task): motion after the recovery is not judged.
        event: the task ends with a final event; False when the fault takes the sequencer
            itself away (its clients learn it from its liveliness token).
        deadman: the arm's side can only learn of it from the heartbeat deadman (a hung
            sequencer keeps its liveliness token): the stop is judged against the limit
            grown by the cycles that deadman waits (:func:`judge.stop_limit_ns`).
    """

    name: str
    action: Action
    target: str = ""
    sim: dict[str, Any] = field(default_factory=dict)
    hold_s: float = 1.5
    stops: bool = True
    outcome: Outcome = Outcome.FAILED
    reason: tuple[str, ...] = ()
    resumes: bool = False
    event: bool = True
    deadman: bool = False

    def __post_init__(self) -> None:
        signals = (Action.SIGKILL, Action.SIGSTOP)
        if (self.action in signals) != bool(self.target):
            raise ConfigError(f"fault {self.name}: a target iff the action is a signal")
        if (self.action is Action.SIM) != bool(self.sim):
            raise ConfigError(f"fault {self.name}: `sim` fields iff the action is sim")
        if not 0.0 < self.hold_s <= 30.0:
            raise ConfigError(f"fault {self.name}: hold_s {self.hold_s!r} outside (0, 30] s")


def _signals(target: str, liveliness: str, **kw: Any) -> tuple[FaultKind, FaultKind]:
    words = (liveliness, *kw.pop("words", ()))
    return (
        FaultKind(f"{target}_sigkill", Action.SIGKILL, target, reason=words, **kw),
        FaultKind(f"{target}_sigstop", Action.SIGSTOP, target, reason=words, **kw),
    )


_CAN_WORDS = ("joint state", "outage", "gap", "resync", "tolerance")
_STATES = [0x350, 0x360]
"""CAN ids of the arm's status and position frames (the bridge's inputs)."""

FAULTS: tuple[FaultKind, ...] = (
    *_signals("bridge", "can_bridge"),
    *_signals("controller", "controller"),
    # not on the command path: the running move goes on with fresh commands until the
    # sequencer sees the planner's token vanish and cancels it (a deceleration)
    *_signals("planner", "planner", stops=False, outcome=Outcome.ANY),
    FaultKind("sequencer_sigkill", Action.SIGKILL, "sequencer", event=False),
    FaultKind(
        "sequencer_sigstop",
        Action.SIGSTOP,
        "sequencer",
        reason=("heartbeat", "gone"),
        deadman=True,
    ),
    *_signals("record", "recorder", stops=False, outcome=Outcome.SUCCEEDED),
    FaultKind("router_restart", Action.ROUTER, hold_s=1.0, reason=("gone", "link", "heartbeat")),
    FaultKind(
        "can_drop",
        Action.SIM,
        sim={"kind": "drop", "duration_ms": 600.0, "ids": _STATES},
        outcome=Outcome.ANY,
        resumes=True,
        reason=_CAN_WORDS,
    ),
    FaultKind(
        "can_delay",
        Action.SIM,
        sim={"kind": "delay", "duration_ms": 600.0, "delay_ms": 30.0, "ids": [0x360]},
        outcome=Outcome.ANY,
        resumes=True,
        reason=_CAN_WORDS,
    ),
    FaultKind(
        "can_duplicate",
        Action.SIM,
        sim={"kind": "duplicate", "duration_ms": 600.0, "ids": _STATES},
        outcome=Outcome.ANY,
        resumes=True,
        reason=_CAN_WORDS,
    ),
    FaultKind(
        "can_corrupt",
        Action.SIM,
        sim={"kind": "corrupt", "duration_ms": 600.0, "corrupt": "dlc", "ids": _STATES},
        outcome=Outcome.ANY,
        resumes=True,
        reason=_CAN_WORDS,
    ),
    FaultKind(
        "arm_error",
        Action.SIM,
        sim={"kind": "error", "code": 4},
        hold_s=0.5,
        reason=("error",),
    ),
    FaultKind("e_stop", Action.ESTOP, hold_s=0.5, reason=("e-stop", "estop")),
)
"""Every fault kind the soak draws from."""


@dataclass(frozen=True)
class TaskKind:
    """One task of the soak, in the thesis form of ``manus run``: words that are
    ``fold_out`` / ``fold_in``, a via-point file under ``paths/`` or a gripper opening
    [mm]."""

    name: str
    words: tuple[str, ...]
    window_s: float = 2.0
    """the fault comes within this long after the last step starts moving the arm [s]
    (short steps, such as the gripper's, end sooner)"""

    def task(self) -> Task:
        """The :class:`Task` to submit."""
        steps: list[TaskStep] = []
        for word in self.words:
            if word in ("fold_out", "fold_in"):
                steps.append(TaskStep(kind=word, where=word))
            elif word.endswith(".txt"):
                steps.append(TaskStep(kind="move", path=load_path(PATHS / word), where=word))
            else:
                steps.append(TaskStep(kind="gripper", opening=float(word) * 1e-3, where=word))
        return Task(steps=steps, name=f"chaos {self.name}")


TASKS: tuple[TaskKind, ...] = (
    TaskKind("square", ("fold_out", "thesis_square.txt")),
    TaskKind("gripper", ("fold_out", "40", "5", "40"), window_s=0.4),
    TaskKind("circle", ("fold_out", "thesis_circle.txt")),
    TaskKind("fold", ("fold_in", "fold_out")),
)
"""The tasks run back to back, in turn."""


Row = TypeVar("Row", FaultKind, TaskKind)


@dataclass(frozen=True)
class Round:
    """One round of the soak: a task, and the fault that hits it ``delay_s`` after the
    arm starts moving."""

    index: int
    task: TaskKind
    fault: FaultKind
    delay_s: float


def select(names: str, table: tuple[Row, ...], what: str) -> tuple[Row, ...]:
    """The rows of ``table`` named in ``names`` (comma-separated, in the table's order;
    empty: the whole table), for a targeted soak.

    Raises:
        ConfigError: a name that is not in the table (naming the known ones).
    """
    wanted = [n.strip() for n in names.split(",") if n.strip()]
    if not wanted:
        return table
    known = [row.name for row in table]
    unknown = [n for n in wanted if n not in known]
    if unknown:
        raise ConfigError(f"unknown {what} {', '.join(unknown)} (known: {', '.join(known)})")
    return tuple(row for row in table if row.name in wanted)


def draw(
    seed: int,
    rounds: int,
    faults: tuple[FaultKind, ...] = FAULTS,
    tasks: tuple[TaskKind, ...] = TASKS,
) -> list[Round]:
    """The schedule: tasks in turn, faults in a seeded shuffled order (each kind once
    before any repeats), delays uniform in [0.15, 1] x the task's ``window_s``."""
    rng = np.random.default_rng(seed)
    order: list[int] = []
    while len(order) < rounds:
        order.extend(int(i) for i in rng.permutation(len(faults)))
    out = []
    for i in range(rounds):
        task = tasks[i % len(tasks)]
        delay = round(float(rng.uniform(0.15, 1.0)) * task.window_s, 3)
        out.append(Round(i, task, faults[order[i]], delay))
    return out
