"""The truth on disk: one line per cycle, independent of Zenoh (``manus sim --truth-log``).

A soak that cuts the Zenoh links (a router restart) still needs the arm's true motion
through the outage; the bus cannot carry it then, so the simulator also writes it
locally. One line per snapshot, whitespace-separated::

    stamp_ns seq q1 q2 q3 q4 q5 q6 gripper       # ns, -, rad x 6 (true DH angles), m

flushed line by line (a reader may follow the file while the simulator runs).
"""

from __future__ import annotations

from pathlib import Path
from typing import IO, NamedTuple

from schemas.state import SimTruth


class TruthLine(NamedTuple):
    """One line of a truth log.

    Attributes:
        stamp_ns: simulator time of the snapshot [ns].
        seq: snapshot number of this log.
        q: true DH joint angles [rad] (6,).
        gripper: true gripper opening [m].
    """

    stamp_ns: int
    seq: int
    q: tuple[float, ...]
    gripper: float


class TruthLog:
    """Appends each truth it is called with to ``path`` (see the module docstring)."""

    def __init__(self, path: str | Path) -> None:
        self._stream: IO[str] = open(path, "w", encoding="ascii", buffering=1)  # noqa: SIM115
        self._seq = 0

    def __call__(self, truth: SimTruth) -> None:
        """Write one line."""
        values = " ".join(repr(float(v)) for v in (*truth.q_true, truth.gripper))
        self._stream.write(f"{truth.stamp_ns} {self._seq} {values}\n")
        self._seq += 1

    def close(self) -> None:
        """Close the file."""
        self._stream.close()


def read_truth_log(path: str | Path) -> list[TruthLine]:
    """Every complete line of a truth log (a torn last line is skipped)."""
    lines: list[TruthLine] = []
    with open(path, encoding="ascii") as stream:
        for text in stream:
            parts = text.split()
            if not text.endswith("\n") or len(parts) != 9:
                continue
            values = [float(p) for p in parts[2:]]
            lines.append(TruthLine(int(parts[0]), int(parts[1]), tuple(values[:6]), values[6]))
    return lines
