"""Recorded outputs against replayed ones: the comparison of a regression check
(:mod:`manus_stack.regression`), exact or within a stated float tolerance.

Each output is compared with the recorded message of the same channel and rank. Equal
encoded bytes are equal. Otherwise both are decoded and compared field by field: keys,
lengths, types, strings, integers and booleans exactly; floats exactly (:data:`EXACT`)
or within a relative tolerance (:data:`CPU_ROUNDING`, what the checks use). The first
difference reported is the one caused by the earliest input.

Why a tolerance, and how large. The same inputs give the same outputs on one machine, bit
for bit; not on every CPU. NumPy picks a SIMD implementation of its vectorised functions
(``sin``, ``cos``, ``arctan2``, ``hypot``, sums) at import from the CPU's features,
OpenBLAS a kernel for ``solve``, ``eigvals`` and matrix products, and glibc's libm (which
Python's ``math`` calls) an FMA variant of ``sin``, ``cos``, ``atan2``, ``exp`` on CPUs
that have FMA; each rounds differently, by a unit in the last place or a few. Measured
on the thesis paths (``docs/testing.md``, "The same on every CPU"): the planner's plans
differ by up to 1.0e-15 relative between NumPy's baseline and AVX-512 dispatch and
between OpenBLAS kernels; the controller's commands (integer counts) not at all, its
feedback's Cartesian position (forward kinematics through ``math``) by 1.1e-16 without
FMA. :data:`CPU_ROUNDING` allows 1e-9 relative to ``max(1, |value|)``: 1 nrad on a joint
angle, 1 nm on a position, 1 ns on a time. That is six orders of magnitude above the
rounding, and six below anything the arm can show (its joint resolution is 0.1 deg,
1.7 mrad; its command resolution 0.1 deg per 20 ms tick), so a real change of a core still
fails the check; integers (every command count) are never within a tolerance.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import msgpack

from services.recorder.reading import Recorded


@dataclass(frozen=True)
class Tolerance:
    """How far a replayed float may be from the recorded one.

    Attributes:
        relative: largest ``|a - b| / max(1, |a|, |b|)`` accepted (0: bit for bit).
        why: what the tolerance covers (shown with a check's result).
    """

    relative: float
    why: str

    def allows(self, deviation: float) -> bool:
        """Whether a :func:`deviation` is within the tolerance."""
        return deviation <= self.relative


EXACT = Tolerance(0.0, "bit for bit")
CPU_ROUNDING = Tolerance(
    1e-9, "NumPy's SIMD dispatch, OpenBLAS's kernels and glibc's libm round differently by CPU"
)
"""Floats within 1e-9 relative to ``max(1, |value|)`` (see the module docstring)."""


def deviation(recorded: float, replayed: float) -> float:
    """Relative difference of two floats: ``|a - b| / max(1, |a|, |b|)``; 0 for equal
    values (two NaNs, two equal infinities included), ``inf`` when only one is finite."""
    if recorded == replayed or (math.isnan(recorded) and math.isnan(replayed)):
        return 0.0
    if not (math.isfinite(recorded) and math.isfinite(replayed)):
        return math.inf
    return abs(recorded - replayed) / max(1.0, abs(recorded), abs(replayed))


def first_difference(
    recorded: Any, replayed: Any, path: str = "", tolerance: Tolerance = EXACT
) -> tuple[str, Any, Any] | None:
    """The first (depth-first) field where two plain values differ beyond ``tolerance``:
    (path, a, b); None when they match."""
    if isinstance(recorded, dict) and isinstance(replayed, dict):
        return _first_in_maps(recorded, replayed, path, tolerance)
    if isinstance(recorded, list) and isinstance(replayed, list):
        return _first_in_lists(recorded, replayed, path, tolerance)
    if type(recorded) is not type(replayed):
        return path, recorded, replayed
    if isinstance(recorded, float):
        same = tolerance.allows(deviation(recorded, replayed))
    else:
        same = recorded == replayed
    return None if same else (path, recorded, replayed)


def _first_in_maps(
    recorded: dict[Any, Any], replayed: dict[Any, Any], path: str, tolerance: Tolerance
) -> tuple[str, Any, Any] | None:
    for key in sorted(set(recorded) | set(replayed), key=str):
        sub = f"{path}.{key}" if path else str(key)
        if key not in recorded or key not in replayed:
            return sub, recorded.get(key), replayed.get(key)
        found = first_difference(recorded[key], replayed[key], sub, tolerance)
        if found:
            return found
    return None


def _first_in_lists(
    recorded: list[Any], replayed: list[Any], path: str, tolerance: Tolerance
) -> tuple[str, Any, Any] | None:
    for i, (a, b) in enumerate(zip(recorded, replayed, strict=False)):
        found = first_difference(a, b, f"{path}[{i}]", tolerance)
        if found:
            return found
    if len(recorded) != len(replayed):
        return f"{path} (length)", len(recorded), len(replayed)
    return None


def largest_deviation(recorded: Any, replayed: Any) -> float:
    """The largest :func:`deviation` between the floats at the same place in two plain
    values of the same shape (0 when they hold no float, or equal ones)."""
    if isinstance(recorded, dict) and isinstance(replayed, dict):
        pairs = [(recorded[k], replayed[k]) for k in recorded if k in replayed]
    elif isinstance(recorded, list) and isinstance(replayed, list):
        pairs = list(zip(recorded, replayed, strict=False))
    elif isinstance(recorded, float) and isinstance(replayed, float):
        return deviation(recorded, replayed)
    else:
        return 0.0
    return max((largest_deviation(a, b) for a, b in pairs), default=0.0)


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


@dataclass(frozen=True)
class CheckResult:
    """Outcome of one check.

    Attributes:
        service: the core checked.
        inputs: inputs fed to it.
        compared: outputs compared (identical ones included).
        recorded: recorded outputs.
        replayed: outputs the core produced.
        difference: the first difference (None: identical, or within the tolerance).
        tolerance: the float tolerance of the comparison.
        deviation: the largest relative float deviation among the outputs compared
            that were accepted (0: bit for bit; at most ``tolerance.relative``).
    """

    service: str
    inputs: int
    compared: int
    recorded: int
    replayed: int
    difference: Difference | None
    tolerance: Tolerance = EXACT
    deviation: float = 0.0

    @property
    def ok(self) -> bool:
        """Every output identical (within the tolerance)."""
        return self.difference is None


def plain(payload: bytes) -> Any:
    """A MessagePack payload as plain values (the bytes themselves when it does not
    decode)."""
    try:
        return msgpack.unpackb(payload, raw=False, strict_map_key=False)
    except (ValueError, msgpack.ExtraData, msgpack.FormatError, msgpack.StackError):
        return payload


class Comparer:
    """Collects replayed outputs and compares them with the recorded ones per channel.

    Args:
        recorded: the recorded outputs per channel, in log-time order.
        last_ns: log time up to which inputs are fed [ns].
        tolerance: how replayed floats are compared.
    """

    def __init__(
        self, recorded: dict[str, list[Recorded]], last_ns: int, tolerance: Tolerance = EXACT
    ) -> None:
        self.recorded = recorded
        self.last_ns = last_ns
        self.tolerance = tolerance
        self.replayed: dict[str, list[tuple[int, bytes]]] = {s: [] for s in recorded}

    def add(self, suffix: str, payload: bytes, input_ns: int) -> None:
        """One replayed output on ``suffix``, produced by the input logged at ``input_ns``."""
        self.replayed.setdefault(suffix, []).append((input_ns, payload))

    def result(self, service: str, inputs: int) -> CheckResult:
        """Compare everything collected (the earliest difference over all channels)."""
        best: Difference | None = None
        compared = 0
        worst = 0.0
        for suffix in sorted(set(self.recorded) | set(self.replayed)):
            recs = self.recorded.get(suffix, [])
            reps = self.replayed.get(suffix, [])
            diff: Difference | None = None
            for rank in range(max(len(recs), len(reps))):
                rec = recs[rank] if rank < len(recs) else None
                rep = reps[rank] if rank < len(reps) else None
                if rec is not None and rep is not None:
                    compared += 1
                    if rec.payload == rep[1]:
                        continue
                    a, b = plain(rec.payload), plain(rep[1])
                    found = first_difference(a, b, tolerance=self.tolerance)
                    if found is None and self.tolerance.relative > 0.0 and a != b:
                        worst = max(worst, largest_deviation(a, b))
                        continue  # within the tolerance (bit for bit: any byte differs)
                    found = found or ("", a, b)
                    diff = Difference(suffix, rank, rep[0], found[0], found[1], found[2])
                elif rep is not None:
                    diff = Difference(suffix, rank, rep[0], "", None, plain(rep[1]))
                elif rec is not None:
                    diff = Difference(suffix, rank, rec.log_ns, "", plain(rec.payload), None)
                break
            if diff is not None and (best is None or diff.input_ns < best.input_ns):
                best = diff
        return CheckResult(
            service,
            inputs,
            compared,
            sum(map(len, self.recorded.values())),
            sum(map(len, self.replayed.values())),
            best,
            self.tolerance,
            worst,
        )
