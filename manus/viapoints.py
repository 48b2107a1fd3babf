"""Via-point files (docs/protocol.md, Thesis via-point format) <-> :class:`schemas.planning.Path`.

One via point per line, 14 whitespace-separated columns, in the thesis's units:

    X Y Z   Vx Vy Vz   Yaw Roll Pitch   Vyaw Vroll Vpitch   time   type
    mm      mm/s       deg              deg/s               s      0|1|2

``#`` starts a comment (whole line or end of line); blank lines are skipped. ``type`` is
0 absolute (base frame), 1 relative to the first via point, 2 relative to the previous
one. ``time`` is the arrival time since the first via point: the first via point is at
0 and times increase strictly. The first via point stands for the gripper's pose when
the plan is made (its coordinates are ignored); only the first and last velocities are
used. The file's angle order is yaw, ROLL, pitch; the message's is (yaw, pitch, roll)
with R = Rz(yaw) Ry(pitch) Rx(roll) (:mod:`manus.orientation`).

Every rule has one error, :class:`ViaPointError`, naming the file, line, column, value
and the rule. Messages built by other programs go through the same rules with
:func:`validate_path`.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Sequence
from pathlib import Path as FilePath

from manus.errors import ManusError
from schemas.planning import Path, ViaPoint

COLUMNS = (
    *("X", "Y", "Z", "Vx", "Vy", "Vz"),
    *("Yaw", "Roll", "Pitch", "Vyaw", "Vroll", "Vpitch"),
    *("time", "type"),
)
"""Column names of a via-point line, in file order."""

UNITS = ("mm",) * 3 + ("mm/s",) * 3 + ("deg",) * 3 + ("deg/s",) * 3 + ("s", "")
"""Unit of each column, in file order."""

# Largest magnitudes accepted, in file units: far beyond any arm, small enough that a
# typo (a missing decimal point, a value in the wrong column) is caught here.
MAX_TIME_S = 86_400.0
"""Longest path accepted [s] (one day)."""

MAX_ABS = (10_000.0,) * 3 + (10_000.0,) * 3 + (3600.0,) * 3 + (3600.0,) * 3 + (MAX_TIME_S, 2.0)
"""Per column: |X..Z| <= 10 m, |Vx..Vz| <= 10 m/s, |angle| <= 10 turns, |rate| <= 10
turns/s, time <= 1 day."""

TYPES = {0: "absolute", 1: "relative to the first via point", 2: "relative to the previous one"}

_NUMBER = re.compile(r"[+-]?(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_NOT_FINITE = {"nan", "inf", "infinity"}
_MM, _DEG = 1e-3, math.pi / 180.0


class ViaPointError(ManusError, ValueError):
    """A via-point file or path breaks a rule of the format.

    Attributes:
        source: file name (or the path's ``source``).
        line: 1-based line in the file (0: not from a file).
        via_point: 0-based via point index (-1: not one via point).
        column: column name (``COLUMNS``), empty when the whole line is wrong.
        value: the offending text or value, empty when there is none.
        rule: what is allowed, in words.
    """

    def __init__(
        self,
        *,
        source: str,
        rule: str,
        line: int = 0,
        via_point: int = -1,
        column: str = "",
        value: str = "",
    ) -> None:
        where = source or "<path>"
        if line:
            where += f":{line}"
        if via_point >= 0:
            where += f": via point {via_point}"
        what = f": column {column} = {value}" if column else ""
        super().__init__(f"{where}{what}: {rule}")
        self.source, self.line, self.via_point = source, line, via_point
        self.column, self.value, self.rule = column, value, rule


def parse_viapoints(text: str, source: str = "<text>") -> Path:
    """Parse via-point text into a :class:`Path` in SI units, keeping each line number.

    Raises:
        ViaPointError: the first broken rule, naming ``source``, line and column.
    """
    rows: list[list[float]] = []
    lines: list[int] = []
    for number, raw in enumerate(text.removeprefix("\ufeff").split("\n"), start=1):
        tokens = raw.split("#", 1)[0].split()
        if not tokens:
            continue
        if len(tokens) != len(COLUMNS):
            raise ViaPointError(
                source=source,
                line=number,
                via_point=len(rows),
                rule=f"expected {len(COLUMNS)} columns ({' '.join(COLUMNS)}), got {len(tokens)}",
            )
        rows.append(
            [_number(tok, source, number, len(rows), col) for col, tok in enumerate(tokens)]
        )
        lines.append(number)
    return path_from_rows(rows, source=source, lines=lines)


def load_path(file: str | os.PathLike[str]) -> Path:
    """Read and parse a via-point file (UTF-8 text).

    Raises:
        ViaPointError: unreadable, not text, or breaking a rule (naming the line).
    """
    name = os.fspath(file)
    try:
        data = FilePath(name).read_bytes()
    except OSError as exc:
        raise ViaPointError(source=name, rule=f"cannot read the file: {exc.strerror}") from exc
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise ViaPointError(
            source=name, line=line, rule=f"not UTF-8 text (byte {data[exc.start]:#04x})"
        ) from exc
    return parse_viapoints(text, source=name)


def path_from_rows(
    rows: Sequence[Sequence[float]], *, source: str = "", lines: Sequence[int] | None = None
) -> Path:
    """A :class:`Path` from rows of the 14 file columns in file units (mm, deg, s).

    Args:
        rows: one row per via point, ``COLUMNS`` order.
        source: name for error messages and :attr:`Path.source`.
        lines: source line of each row (default: none, 0).

    Raises:
        ViaPointError: a row breaks a rule (column count, finiteness, magnitude, type,
            time order, fewer than two via points).
    """
    lines = list(lines) if lines is not None else [0] * len(rows)
    checked = _checked_rows(rows, source, lines)
    return Path(
        via_points=[_via_point(v, line) for v, line in zip(checked, lines, strict=True)],
        source=source,
    )


def _checked_rows(
    rows: Sequence[Sequence[float]], source: str, lines: list[int]
) -> list[list[float]]:
    """``rows`` as floats, after every rule of :func:`path_from_rows`."""
    if len(lines) != len(rows):
        raise ViaPointError(source=source, rule=f"{len(rows)} rows but {len(lines)} line numbers")
    if not rows:
        raise ViaPointError(source=source, rule="no via points (empty file or only comments)")
    checked = []
    previous_time = -math.inf
    for index, (row, line) in enumerate(zip(rows, lines, strict=True)):
        if len(row) != len(COLUMNS):
            raise ViaPointError(
                source=source,
                line=line,
                via_point=index,
                rule=f"expected {len(COLUMNS)} columns ({' '.join(COLUMNS)}), got {len(row)}",
            )
        values = [float(v) for v in row]
        for col, v in enumerate(values):
            _check_magnitude(v, source, line, index, col)
        time = values[12]
        if index == 0 and time != 0.0:
            raise _column_error(
                source,
                line,
                index,
                12,
                time,
                "the first via point is the start: its time must be 0",
            )
        if index > 0 and not time > previous_time:
            raise _column_error(
                source,
                line,
                index,
                12,
                time,
                f"must be after the previous via point's time {previous_time:g} s "
                "(times are arrival times since the first via point, strictly increasing)",
            )
        previous_time = time
        checked.append(values)
    if len(checked) < 2:
        raise ViaPointError(
            source=source,
            line=lines[0],
            rule="a path needs at least two via points (the first stands for the start pose)",
        )
    return checked


def path_to_rows(path: Path) -> list[list[float]]:
    """The 14 file columns of each via point, in file units (the inverse of
    :func:`path_from_rows`)."""
    rows = []
    for vp in path.via_points:
        yaw, pitch, roll = (a / _DEG for a in vp.ypr)
        vyaw, vpitch, vroll = (a / _DEG for a in vp.angular_velocity)
        rows.append(
            [
                *(x / _MM for x in vp.xyz),
                *(v / _MM for v in vp.velocity),
                yaw,
                roll,
                pitch,
                vyaw,
                vroll,
                vpitch,
                vp.time,
                float(vp.type),
            ]
        )
    return rows


def format_path(path: Path, *, header: bool = True) -> str:
    """Via-point text of ``path`` (parses back to the same values, to 12 digits)."""
    out = []
    if header:
        out.append(f"# {' '.join(COLUMNS)}")
        out.append(f"# {' '.join(u or '-' for u in UNITS)}")
    for row in path_to_rows(path):
        cells = [f"{v:.12g}" for v in row[:13]] + [str(int(row[13]))]
        out.append(" ".join(cells))
    return "\n".join(out) + "\n"


def validate_path(path: Path) -> None:
    """Apply the file rules to a :class:`Path` built by another program.

    Raises:
        ViaPointError: naming the via point, its line (when it has one) and the column.
    """
    _checked_rows(path_to_rows(path), path.source, [vp.line for vp in path.via_points])


def _number(token: str, source: str, line: int, index: int, col: int) -> float:
    if not _NUMBER.fullmatch(token):
        rule = (
            "not a finite number"
            if token.lower().lstrip("+-") in _NOT_FINITE
            else "not a number (expected e.g. 12, -0.5, 1e-3)"
        )
        raise ViaPointError(
            source=source, line=line, via_point=index, column=COLUMNS[col], value=token, rule=rule
        )
    value = float(token)
    if not math.isfinite(value):
        raise ViaPointError(
            source=source,
            line=line,
            via_point=index,
            column=COLUMNS[col],
            value=token,
            rule="too large to be a number",
        )
    return value


def _check_magnitude(value: float, source: str, line: int, index: int, col: int) -> None:
    if not math.isfinite(value):
        raise _column_error(source, line, index, col, value, "not a finite number")
    if col == 13:
        if value not in TYPES:
            allowed = ", ".join(f"{k} {v}" for k, v in TYPES.items())
            raise _column_error(
                source, line, index, col, value, f"unknown type (allowed: {allowed})"
            )
        return
    if col == 12 and value < 0.0:
        raise _column_error(source, line, index, col, value, "time must not be negative")
    if abs(value) > MAX_ABS[col]:
        raise _column_error(
            source,
            line,
            index,
            col,
            value,
            f"|{COLUMNS[col]}| must be at most {MAX_ABS[col]:g} {UNITS[col]}".rstrip(),
        )


def _column_error(
    source: str, line: int, index: int, col: int, value: float, rule: str
) -> ViaPointError:
    unit = f" {UNITS[col]}" if UNITS[col] else ""
    return ViaPointError(
        source=source,
        line=line,
        via_point=index,
        column=COLUMNS[col],
        value=f"{value:g}{unit}",
        rule=rule,
    )


def _via_point(v: list[float], line: int) -> ViaPoint:
    return ViaPoint(
        xyz=[v[0] * _MM, v[1] * _MM, v[2] * _MM],
        velocity=[v[3] * _MM, v[4] * _MM, v[5] * _MM],
        ypr=[v[6] * _DEG, v[8] * _DEG, v[7] * _DEG],
        angular_velocity=[v[9] * _DEG, v[11] * _DEG, v[10] * _DEG],
        time=v[12],
        type=int(v[13]),
        line=line,
    )
