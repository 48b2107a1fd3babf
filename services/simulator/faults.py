"""Fault injection: what can go wrong on the arm's side, switchable per run, seeded.

Four families, each a frozen, validated value; a :class:`FaultConfig` holds any number of
each, and :class:`services.simulator.core.SimCore.add_fault` adds more at run time:

- :class:`FrameFault`: ``drop``, ``duplicate``, ``delay`` or ``corrupt`` outgoing frames,
  each frame hit with probability ``rate`` while the fault is on (``start_ms`` for
  ``duration_ms`` or for ``count`` hits; ``rate=1`` makes a burst).
- :class:`Silence`: the arm sends nothing for a while (its cycle keeps running inside).
- :class:`InjectedMessage`: a warning (held for ``duration_ms``) or an error (latched until
  a 0x370 stop) reported in the status byte from ``at_ms``.
- :class:`StuckJoint`: one motor stops moving (the arm raises "motor blocked" while it
  is commanded to move).

Times are simulator time since power-up [ms].
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from manus.errors import ConfigError
from manus.protocol import Frame
from services.simulator.counters import SimCounters

FRAME_FAULT_KINDS = ("drop", "duplicate", "delay", "corrupt")
CORRUPTIONS = ("bits", "dlc")
DUPLICATE_GAP_NS = 500_000
"""Gap between a frame and its duplicate [ns] (about one frame time at 250 kbit/s)."""


def _window_ok(name: str, start_ms: float, duration_ms: float | None) -> None:
    if not start_ms >= 0.0:
        raise ConfigError(f"{name}: `start_ms` must be >= 0 ms, got {start_ms!r}")
    if duration_ms is not None and not duration_ms > 0.0:
        raise ConfigError(f"{name}: `duration_ms` must be > 0 ms or null, got {duration_ms!r}")


def _inside(t_ns: int, start_ms: float, duration_ms: float | None) -> bool:
    start = round(start_ms * 1e6)
    return t_ns >= start and (duration_ms is None or t_ns < start + round(duration_ms * 1e6))


@dataclass(frozen=True)
class FrameFault:
    """A fault on the frames the arm sends.

    Attributes:
        kind: ``drop``, ``duplicate``, ``delay`` or ``corrupt``.
        rate: probability that a frame is hit while the fault is on [0..1].
        start_ms: when the fault turns on [ms].
        duration_ms: how long it stays on [ms]; None: for ever (or until ``count`` hits).
        count: the fault turns off after this many hits; None: no limit.
        ids: only frames with these identifiers are hit; empty: every frame.
        delay_ms: extra latency of a delayed frame [ms] (``delay`` only).
        corrupt: ``bits`` (flip one data bit; a frame without data gets a wrong DLC) or
            ``dlc`` (wrong data length) (``corrupt`` only).
    """

    kind: str
    rate: float = 1.0
    start_ms: float = 0.0
    duration_ms: float | None = None
    count: int | None = None
    ids: tuple[int, ...] = ()
    delay_ms: float = 30.0
    corrupt: str = "bits"

    def __post_init__(self) -> None:
        if self.kind not in FRAME_FAULT_KINDS:
            raise ConfigError(f"frame fault kind {self.kind!r} is not one of {FRAME_FAULT_KINDS}")
        if not 0.0 <= self.rate <= 1.0:
            raise ConfigError(f"{self.kind} fault: `rate` {self.rate!r} outside [0, 1]")
        _window_ok(f"{self.kind} fault", self.start_ms, self.duration_ms)
        if self.count is not None and self.count < 1:
            raise ConfigError(f"{self.kind} fault: `count` must be >= 1, got {self.count!r}")
        if not 0.0 < self.delay_ms <= 10_000.0:
            raise ConfigError(f"delay fault: `delay_ms` {self.delay_ms!r} outside (0, 10000] ms")
        if self.corrupt not in CORRUPTIONS:
            raise ConfigError(f"corrupt fault: `corrupt` {self.corrupt!r} not in {CORRUPTIONS}")
        object.__setattr__(self, "ids", tuple(int(i) for i in self.ids))


@dataclass(frozen=True)
class Silence:
    """The arm sends no frame from ``start_ms`` for ``duration_ms`` [ms] (None: for ever)."""

    start_ms: float
    duration_ms: float | None = None

    def __post_init__(self) -> None:
        _window_ok("silence", self.start_ms, self.duration_ms)


@dataclass(frozen=True)
class InjectedMessage:
    """A warning or error code the arm reports from ``at_ms``.

    Attributes:
        msg_class: ``warning`` (held for ``duration_ms``) or ``error`` (latched until a
            0x370 stop becomes active; the arm stops moving meanwhile).
        code: message code (byte 1), 0..255.
        at_ms: when it appears [ms].
        duration_ms: how long a warning holds [ms] (ignored for errors).
    """

    msg_class: str
    code: int
    at_ms: float
    duration_ms: float = 60.0

    def __post_init__(self) -> None:
        if self.msg_class not in ("warning", "error"):
            raise ConfigError(f"injected message class {self.msg_class!r}: use warning or error")
        if not 0 <= self.code <= 255:
            raise ConfigError(f"injected {self.msg_class} code {self.code!r} outside 0..255")
        _window_ok(f"injected {self.msg_class}", self.at_ms, self.duration_ms)


@dataclass(frozen=True)
class StuckJoint:
    """Motor ``joint`` (1..6) stops moving from ``at_ms`` for ``duration_ms`` (None: for ever)."""

    joint: int
    at_ms: float = 0.0
    duration_ms: float | None = None

    def __post_init__(self) -> None:
        if not 1 <= self.joint <= 6:
            raise ConfigError(f"stuck joint {self.joint!r} outside 1..6")
        _window_ok(f"stuck joint {self.joint}", self.at_ms, self.duration_ms)

    def active(self, t_ns: int) -> bool:
        """True while the joint is stuck."""
        return _inside(t_ns, self.at_ms, self.duration_ms)


Fault = FrameFault | Silence | InjectedMessage | StuckJoint


@dataclass(frozen=True)
class FaultConfig:
    """Every fault of one run (none by default)."""

    frames: tuple[FrameFault, ...] = ()
    silences: tuple[Silence, ...] = ()
    messages: tuple[InjectedMessage, ...] = ()
    stuck: tuple[StuckJoint, ...] = ()

    @property
    def all(self) -> tuple[Fault, ...]:
        """Every fault, in family order."""
        return (*self.frames, *self.silences, *self.messages, *self.stuck)

    @classmethod
    def from_mapping(cls, data: Mapping[str, Any], *, source: str = "<mapping>") -> FaultConfig:
        """From JSON-like data: ``{"frames": [{"kind": "drop", "rate": 0.1}], ...}``.

        Raises:
            ConfigError: naming the source, the family and the entry.
        """
        families: dict[str, type[Any]] = {
            "frames": FrameFault,
            "silences": Silence,
            "messages": InjectedMessage,
            "stuck": StuckJoint,
        }
        kwargs: dict[str, tuple[Any, ...]] = {}
        for key, entries in data.items():
            if key not in families:
                raise ConfigError(f"{source}: unknown fault family `{key}` ({sorted(families)})")
            if not isinstance(entries, list):
                raise ConfigError(f"{source}: `faults.{key}` must be a list")
            built = []
            for i, entry in enumerate(entries):
                if not isinstance(entry, dict):
                    raise ConfigError(f"{source}: `faults.{key}[{i}]` must be an object")
                kwargs_i = {**entry, "ids": tuple(entry["ids"])} if "ids" in entry else entry
                try:
                    built.append(families[key](**kwargs_i))
                except TypeError as exc:
                    raise ConfigError(f"{source}: `faults.{key}[{i}]`: {exc}") from exc
                except ConfigError as exc:
                    raise ConfigError(f"{source}: `faults.{key}[{i}]`: {exc}") from exc
            kwargs[key] = tuple(built)
        return cls(**kwargs)


@dataclass
class _Armed:
    fault: FrameFault
    hits: int = 0


@dataclass
class FrameFaulter:
    """Applies the frame faults and silences to each outgoing frame (seeded).

    Attributes:
        rng: the generator every random choice comes from.
        counters: where dropped / duplicated / delayed / corrupted / silenced are counted.
    """

    rng: np.random.Generator
    counters: SimCounters
    _faults: list[_Armed] = field(default_factory=list)
    _silences: list[Silence] = field(default_factory=list)

    def add(self, fault: FrameFault | Silence) -> None:
        """Turn one more fault on."""
        if isinstance(fault, Silence):
            self._silences.append(fault)
        else:
            self._faults.append(_Armed(fault))

    def clear(self) -> None:
        """Turn every frame fault and silence off."""
        self._faults.clear()
        self._silences.clear()

    def apply(self, frame: Frame) -> list[Frame]:
        """What actually goes out for ``frame`` (stamped with its send time): 0, 1 or 2 frames."""
        t = frame.t_ns
        if any(_inside(t, s.start_ms, s.duration_ms) for s in self._silences):
            self.counters.silenced += 1
            return []
        out = [frame]
        for armed in self._faults:
            f = armed.fault
            if not _inside(t, f.start_ms, f.duration_ms) or (f.ids and frame.id not in f.ids):
                continue
            if f.count is not None and armed.hits >= f.count:
                continue
            if f.rate < 1.0 and self.rng.random() >= f.rate:
                continue
            armed.hits += 1
            out = self._hit(f, out)
            if not out:
                break
        return out

    def _hit(self, f: FrameFault, frames: list[Frame]) -> list[Frame]:
        if f.kind == "drop":
            self.counters.dropped += len(frames)
            return []
        if f.kind == "duplicate":
            self.counters.duplicated += len(frames)
            return [g for fr in frames for g in (fr, fr.at(fr.t_ns + DUPLICATE_GAP_NS))]
        if f.kind == "delay":
            self.counters.delayed += len(frames)
            return [fr.at(fr.t_ns + round(f.delay_ms * 1e6)) for fr in frames]
        self.counters.corrupted += len(frames)
        return [self._corrupt(fr, f.corrupt) for fr in frames]

    def _corrupt(self, frame: Frame, how: str) -> Frame:
        if how == "bits" and frame.data:
            flipped = bytearray(frame.data)
            bit = int(self.rng.integers(0, 8 * len(flipped)))
            flipped[bit // 8] ^= 1 << (bit % 8)
            return Frame(frame.id, bytes(flipped), frame.remote, frame.t_ns)
        # A wrong DLC: a different length from the one the protocol fixes.
        wrong = [n for n in range(9) if n != frame.dlc]
        dlc = int(wrong[int(self.rng.integers(0, len(wrong)))])
        if frame.remote:
            return Frame(frame.id, b"", True, frame.t_ns, dlc)
        data = (frame.data + bytes(8))[:dlc]
        return Frame(frame.id, data, False, frame.t_ns)


def parse_fault_list(entries: Sequence[Fault]) -> FaultConfig:
    """A :class:`FaultConfig` holding ``entries`` sorted into their families."""
    return FaultConfig(
        frames=tuple(e for e in entries if isinstance(e, FrameFault)),
        silences=tuple(e for e in entries if isinstance(e, Silence)),
        messages=tuple(e for e in entries if isinstance(e, InjectedMessage)),
        stuck=tuple(e for e in entries if isinstance(e, StuckJoint)),
    )
