"""Task scripts -> :class:`schemas.sequencing.Task`: the thesis form and TOML task files.

**Thesis form** (docs/protocol.md, Thesis task form): via-point files and gripper openings [mm],
alternating, in execution order, as on the thesis's command line::

    manus run paths/thesis_square.txt 40 paths/thesis_circle.txt 0

A word that reads as a number is a gripper opening, anything else a via-point file.

**Task file** (``.toml``, read with the standard library's ``tomllib``): optional
``name`` and ``mode`` (controller mode of the move steps: ``default`` or ``thesis``), then
one ``[[step]]`` table per step, holding exactly one of these keys::

    [[step]]
    fold_out = true                  # fold the arm out (the arm's own motion)
    [[step]]
    move = "square.txt"              # a via-point file, relative to the task file
    interpolation = "quintic"        # optional: cubic (default) or quintic
    speed_scaling = true             # optional: stretch time instead of refusing
    [[step]]
    move = [                         # or inline via points, in the file's 14 columns
      [0, 0, 0,  0, 0, 0,  0, 0, 0,  0, 0, 0,  0.0, 2],
      [0, 50, 0, 0, 0, 0,  0, 0, 0,  0, 0, 0,  2.0, 2],
    ]
    [[step]]
    gripper = 40                     # opening [mm], 0..90
    [[step]]
    wait = 1.5                       # [s]
    [[step]]
    pose = "home"                    # home, unfolded or folded (planned like a path)
    duration = 4.0                   # optional: shortest time of that move [s]
    [[step]]
    follow = "mouth"                 # follow a tracker's target to a standoff and hold it
    offset_mm = [0, 0, 60]           # optional keys: services/sequencer/follow_spec.py
    hold_s = 10                      # (without it: until `manus task done`)
    reach = {pose = [560, 100, -150, 0, 90, 0]}   # a goal the planner finds its way to
                                     # (named, pose, joints, object, approach, line_to,
                                     # line_tool: manus/goal_spec.py, docs/reach.md)
    [[step]]
    pick = "cup"                     # pick, place and give: the world model's objects
    [[step]]                         # (services/sequencer/taskfile_objects.py, docs/pick.md)
    place = "cup"
    at = [950, -150, 790, 0, 0, 0]   # or on = "table"
    [[step]]
    fold_in = true

Every problem of the file is found in one pass and reported together
(:class:`TaskFileError`), each with its location (``file:line: step N (kind): ...``).
"""

from __future__ import annotations

import math
import re
import tomllib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path as FilePath
from typing import Any

from manus.errors import ManusError
from manus.goal_spec import GoalSpecError, goal_from_spec
from manus.viapoints import COLUMNS, ViaPointError, load_path, path_from_rows
from schemas.planning import INTERPOLATIONS
from schemas.sequencing import DEFAULT_POSE_DURATION_S, StepKind, Task, TaskStep
from services.sequencer.follow_spec import OPTIONS as FOLLOW_OPTIONS
from services.sequencer.follow_spec import follow_step
from services.sequencer.poses import POSES
from services.sequencer.taskfile_objects import OBJECT_OPTIONS, object_step

MAX_OPENING_MM = 90.0
"""Largest gripper opening [mm] (the Manus gripper opens to 90 mm)."""

MAX_WAIT_S = 3600.0
"""Longest wait step [s]."""

KINDS = tuple(StepKind)
OPTIONS: dict[str, tuple[str, ...]] = {
    StepKind.MOVE: ("interpolation", "speed_scaling"),
    StepKind.POSE: ("interpolation", "duration"),
    StepKind.GRIPPER: (),
    StepKind.FOLD_IN: (),
    StepKind.FOLD_OUT: (),
    StepKind.WAIT: (),
    StepKind.FOLLOW: FOLLOW_OPTIONS,
    StepKind.REACH: (),
    **OBJECT_OPTIONS,
}
"""Keys a step of each kind may carry besides its kind."""

_STEP_HEADER = re.compile(r"^\s*\[\[\s*step\s*\]\]")
_NUMBER = re.compile(r"^[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?$")


class TaskFileError(ManusError, ValueError):
    """A task script has problems; :attr:`errors` lists every one with its location."""

    def __init__(self, errors: Sequence[str]) -> None:
        self.errors = list(errors)
        super().__init__(f"{len(self.errors)} problem(s) in the task:\n  " + "\n  ".join(errors))


def task_from_args(words: Sequence[str], *, name: str = "", mode: str = "default") -> Task:
    """The thesis form: via-point files and openings [mm], alternating, in order.

    Raises:
        TaskFileError: every file that does not parse and every opening out of range,
            each naming the argument (1-based) and, for files, the line.
    """
    if not words:
        raise TaskFileError(["no steps: give via-point files and gripper openings [mm]"])
    steps: list[TaskStep] = []
    errors: list[str] = []
    for i, word in enumerate(words, start=1):
        where = f"argument {i} ({word})"
        if _NUMBER.match(word):
            opening_mm = float(word)
            problem = _opening_problem(opening_mm)
            if problem:
                errors.append(f"{where}: step {i}: {problem}")
            steps.append(TaskStep(kind=StepKind.GRIPPER, opening=opening_mm * 1e-3, where=where))
            continue
        try:
            path = load_path(word)
        except ViaPointError as exc:
            errors.append(f"{where}: step {i}: {exc}")
            continue
        steps.append(TaskStep(kind=StepKind.MOVE, path=path, where=word))
    if errors:
        raise TaskFileError(errors)
    return Task(steps=steps, name=name or " ".join(words), mode=mode)


def load_task_file(file: str | FilePath) -> Task:
    """Read a TOML task file (see the module docstring).

    Raises:
        TaskFileError: the file cannot be read, is not TOML, or has problems; every
            problem is listed with ``file:line``, the step and the key.
    """
    source = str(file)
    try:
        text = FilePath(file).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise TaskFileError([f"{source}: cannot read the task file: {exc}"]) from exc
    return parse_task_text(text, source=source, base=FilePath(file).resolve().parent)


def parse_task_text(text: str, *, source: str = "<task>", base: FilePath | None = None) -> Task:
    """Parse TOML task text; via-point file names are relative to ``base``.

    Raises:
        TaskFileError: as :func:`load_task_file`.
    """
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise TaskFileError([f"{source}: not valid TOML: {exc}"]) from exc
    lines = text.split("\n")
    headers = [n for n, raw in enumerate(lines, start=1) if _STEP_HEADER.match(raw)]
    errors: list[str] = []
    for key in sorted(set(data) - {"name", "mode", "step"}):
        errors.append(
            f"{source}:{_key_line(lines, key, 1, headers[0] if headers else len(lines) + 1)}: "
            f"unknown top-level key {key!r} (allowed: name, mode, step)"
        )
    name = data.get("name", "")
    if not isinstance(name, str):
        errors.append(f"{source}: name must be a string, got {name!r}")
        name = ""
    mode = data.get("mode", "default")
    if mode not in ("default", "thesis"):
        errors.append(f"{source}: mode {mode!r} is not one of ['default', 'thesis']")
        mode = "default"
    raw_steps = data.get("step", [])
    if not isinstance(raw_steps, list) or not raw_steps:
        errors.append(f"{source}: no steps: write one [[step]] table per step")
        raw_steps = []
    steps: list[TaskStep] = []
    for index, raw in enumerate(raw_steps):
        first = headers[index] if index < len(headers) else 0
        last = headers[index + 1] if index + 1 < len(headers) else len(lines) + 1
        ctx = _StepContext(source, lines, index, first, last, base or FilePath.cwd())
        step = ctx.build(raw, errors)
        if step is not None:
            steps.append(step)
    if errors:
        raise TaskFileError(errors)
    return Task(steps=steps, name=name or FilePath(source).stem, mode=mode)


def _opening_problem(opening_mm: float) -> str:
    if not math.isfinite(opening_mm) or not 0.0 <= opening_mm <= MAX_OPENING_MM:
        return f"gripper opening {opening_mm:g} mm is outside 0..{MAX_OPENING_MM:g} mm"
    return ""


def _key_line(lines: list[str], key: str, first: int, last: int) -> int:
    """Line (1-based) of ``key = ...`` between lines ``first`` and ``last`` (else first)."""
    pattern = re.compile(rf"^\s*{re.escape(key)}\s*=")
    for n in range(max(first, 1), min(last, len(lines) + 1)):
        if pattern.match(lines[n - 1]):
            return n
    return first


@dataclass
class _StepContext:
    """Where one ``[[step]]`` table is, for its error messages."""

    source: str
    lines: list[str]
    index: int
    first: int
    last: int
    base: FilePath

    def where(self, key: str | None = None) -> str:
        line = _key_line(self.lines, key, self.first, self.last) if key else self.first
        return f"{self.source}:{line}" if line else self.source

    def error(self, errors: list[str], key: str | None, kind: str, message: str) -> None:
        label = f"step {self.index + 1}" + (f" ({kind})" if kind else "")
        errors.append(f"{self.where(key)}: {label}: {message}")

    def build(self, raw: Any, errors: list[str]) -> TaskStep | None:
        if not isinstance(raw, dict):
            self.error(errors, None, "", "a step must be a table")
            return None
        kinds = [k for k in KINDS if k in raw]
        if len(kinds) != 1:
            found = ", ".join(kinds) if kinds else "none"
            self.error(errors, None, "", f"needs exactly one of {', '.join(KINDS)} (found {found})")
            return None
        kind = kinds[0]
        ok = True
        for key in sorted(set(raw) - {kind} - set(OPTIONS[kind])):
            allowed = ", ".join(OPTIONS[kind]) or "none"
            self.error(errors, key, kind, f"unknown key {key!r} (options of {kind}: {allowed})")
            ok = False
        options = self._options(raw, kind, errors)
        value = raw[kind]
        where = self.where(kind)
        step: TaskStep | None
        if kind == StepKind.MOVE:
            step = self._move(value, where, errors, options)
        elif kind == StepKind.GRIPPER:
            step = self._gripper(value, where, errors)
        elif kind == StepKind.WAIT:
            step = self._wait(value, where, errors)
        elif kind == StepKind.POSE:
            step = self._pose(value, where, errors, options)
        elif kind == StepKind.FOLLOW:
            step = follow_step(raw, where, lambda key, msg: self.error(errors, key, kind, msg))
        elif kind == StepKind.REACH:
            step = self._reach(value, where, errors)
        elif kind in OBJECT_OPTIONS:
            step = object_step(
                kind, raw, where, lambda key, msg: self.error(errors, key, kind, msg)
            )
        else:
            step = TaskStep(kind=kind, where=where)
            if value is not True:
                self.error(errors, kind, kind, f"write {kind} = true (got {value!r})")
                step = None
        return step if ok and options is not None else None

    def _options(self, raw: dict[str, Any], kind: str, errors: list[str]) -> dict[str, Any] | None:
        out: dict[str, Any] = {}
        good = True
        if "interpolation" in raw:
            value = raw["interpolation"]
            if value not in INTERPOLATIONS:
                self.error(
                    errors,
                    "interpolation",
                    kind,
                    f"interpolation {value!r} is not one of {list(INTERPOLATIONS)}",
                )
                good = False
            else:
                out["interpolation"] = value
        if "speed_scaling" in raw:
            value = raw["speed_scaling"]
            if not isinstance(value, bool):
                self.error(
                    errors,
                    "speed_scaling",
                    kind,
                    f"speed_scaling must be true or false, got {value!r}",
                )
                good = False
            else:
                out["speed_scaling"] = value
        if "duration" in raw:
            value = raw["duration"]
            if not _is_number(value) or not 0.1 <= float(value) <= MAX_WAIT_S:
                self.error(
                    errors,
                    "duration",
                    kind,
                    f"duration {value!r} s is outside 0.1..{MAX_WAIT_S:g} s",
                )
                good = False
            else:
                out["duration"] = float(value)
        return out if good else None

    def _move(
        self, value: Any, where: str, errors: list[str], options: dict[str, Any] | None
    ) -> TaskStep | None:
        try:
            if isinstance(value, str):
                file = FilePath(value)
                path = load_path(file if file.is_absolute() else self.base / file)
            elif isinstance(value, list):
                path = self._inline(value)
            else:
                self.error(
                    errors,
                    "move",
                    "move",
                    "move takes a via-point file name or a list of via points",
                )
                return None
        except ViaPointError as exc:
            self.error(errors, "move", "move", str(exc))
            return None
        return TaskStep(kind=StepKind.MOVE, path=path, where=where, **(options or {}))

    def _inline(self, rows: list[Any]) -> Any:
        start = _key_line(self.lines, "move", self.first, self.last)
        # Each row of the inline array is written on its own line: find them to name them.
        row_lines = [
            n
            for n in range(start, min(self.last, len(self.lines) + 1))
            if re.search(r"\[\s*[-+.0-9]", self.lines[n - 1].split("=", 1)[-1])
        ]
        lines = row_lines if len(row_lines) == len(rows) else [start] * len(rows)
        numeric: list[list[float]] = []
        for i, row in enumerate(rows):
            if not isinstance(row, list) or not all(_is_number(v) for v in row):
                raise ViaPointError(
                    source=self.source,
                    line=lines[i],
                    via_point=i,
                    rule="a via point is a list of numbers",
                )
            if len(row) != len(COLUMNS):
                raise ViaPointError(
                    source=self.source,
                    line=lines[i],
                    via_point=i,
                    rule=f"expected {len(COLUMNS)} columns ({' '.join(COLUMNS)}), got {len(row)}",
                )
            numeric.append([float(v) for v in row])
        return path_from_rows(numeric, source=self.source, lines=lines)

    def _reach(self, value: Any, where: str, errors: list[str]) -> TaskStep | None:
        try:
            goal = goal_from_spec(value)
        except GoalSpecError as exc:
            self.error(errors, "reach", "reach", str(exc))
            return None
        return TaskStep(kind=StepKind.REACH, goal=goal, where=where)

    def _gripper(self, value: Any, where: str, errors: list[str]) -> TaskStep | None:
        if not _is_number(value):
            self.error(
                errors, "gripper", "gripper", f"opening must be a number [mm], got {value!r}"
            )
            return None
        problem = _opening_problem(float(value))
        if problem:
            self.error(errors, "gripper", "gripper", problem)
            return None
        return TaskStep(kind=StepKind.GRIPPER, opening=float(value) * 1e-3, where=where)

    def _wait(self, value: Any, where: str, errors: list[str]) -> TaskStep | None:
        if not _is_number(value) or not 0.0 <= float(value) <= MAX_WAIT_S:
            self.error(errors, "wait", "wait", f"wait {value!r} s is outside 0..{MAX_WAIT_S:g} s")
            return None
        return TaskStep(kind=StepKind.WAIT, duration=float(value), where=where)

    def _pose(
        self, value: Any, where: str, errors: list[str], options: dict[str, Any] | None
    ) -> TaskStep | None:
        if value not in POSES:
            self.error(
                errors, "pose", "pose", f"unknown pose {value!r} (known: {', '.join(POSES)})"
            )
            return None
        opts = dict(options or {})
        duration = opts.pop("duration", DEFAULT_POSE_DURATION_S)
        return TaskStep(kind=StepKind.POSE, pose=value, duration=duration, where=where, **opts)


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
