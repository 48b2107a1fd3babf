"""Where a replayed output differs from the recorded one: the first field, both values.

The regression checks (:mod:`manus_stack.regression`) compare outputs as encoded bytes;
when two differ, :func:`first_difference` walks both as plain values (MessagePack maps and
lists) depth-first and names the first field that differs, and :class:`Difference` says
which output it was and which input made it.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class Difference:
    """The first output that differs.

    Attributes:
        suffix: output channel.
        rank: index of the output on that channel (0-based).
        input_ns: log time of the input that produced it (or of the recorded output when
            the replay produced none) [ns].
        path: field path (``velocity[2]``); empty when one side has no message.
        recorded: the recorded value (None: no recorded message).
        replayed: the replayed value (None: no replayed message).
    """

    suffix: str
    rank: int
    input_ns: int
    path: str
    recorded: Any
    replayed: Any

    def __str__(self) -> str:
        where = f"{self.suffix} #{self.rank} (input at {self.input_ns / 1e9:.6f} s)"
        if self.recorded is None:
            return f"{where}: the replay produced an extra message: {self.replayed!r:.200}"
        if self.replayed is None:
            return f"{where}: the replay produced nothing; recorded: {self.recorded!r:.200}"
        field = self.path or "(whole message)"
        return (
            f"{where}: {field}: recorded {self.recorded!r:.120} != replayed {self.replayed!r:.120}"
        )


def first_difference(recorded: Any, replayed: Any, path: str = "") -> tuple[str, Any, Any] | None:
    """The first (depth-first) field where two plain values differ: (path, a, b)."""
    if isinstance(recorded, dict) and isinstance(replayed, dict):
        return _first_in_maps(recorded, replayed, path)
    if isinstance(recorded, list) and isinstance(replayed, list):
        return _first_in_lists(recorded, replayed, path)
    if type(recorded) is not type(replayed) or recorded != replayed:
        return path, recorded, replayed
    return None


def _first_in_maps(
    recorded: dict[Any, Any], replayed: dict[Any, Any], path: str
) -> tuple[str, Any, Any] | None:
    for key in sorted(set(recorded) | set(replayed), key=str):
        sub = f"{path}.{key}" if path else str(key)
        if key not in recorded or key not in replayed:
            return sub, recorded.get(key), replayed.get(key)
        found = first_difference(recorded[key], replayed[key], sub)
        if found:
            return found
    return None


def _first_in_lists(
    recorded: list[Any], replayed: list[Any], path: str
) -> tuple[str, Any, Any] | None:
    for i, (a, b) in enumerate(zip(recorded, replayed, strict=False)):
        found = first_difference(a, b, f"{path}[{i}]")
        if found:
            return found
    if len(recorded) != len(replayed):
        return f"{path} (length)", len(recorded), len(replayed)
    return None
