"""The message machinery: typed dataclasses <-> MessagePack, validated, with JSON Schema.

Every bus message is a frozen dataclass deriving from :class:`Message`. Each field
carries its documentation and unit in its metadata (use :func:`field`), and that one
definition gives the MessagePack codec (:meth:`Message.encode` / :meth:`Message.decode`,
validated on decode) and the language-neutral JSON Schema (:meth:`Message.json_schema`).

Supported field types: ``int``, ``float``, ``bool``, ``str``, ``bytes``, a nested
``Message``, ``list[T]`` of any of these, and ``T | None``.

A ``str`` field with ``choices`` (a tuple, or a ``StrEnum`` class whose members are the
allowed values: the typed states of :mod:`schemas.states`) is checked when a message is
built, not only when it is decoded: ``GoalResult(status="preemted", ...)`` raises a
:class:`~manus.errors.SchemaError` naming the field and the allowed values.
"""

from __future__ import annotations

import dataclasses
import enum
import math
import types
import typing
from collections.abc import Callable
from typing import Any, ClassVar, Self, TypeVar, get_args, get_origin

import msgpack

from manus.errors import SchemaError

M = TypeVar("M", bound="Message")


def field(
    doc: str,
    *,
    unit: str = "",
    default: Any = dataclasses.MISSING,
    default_factory: Any = dataclasses.MISSING,
    length: int | None = None,
    choices: tuple[str, ...] | type[enum.StrEnum] | None = None,
    minimum: float | None = None,
    maximum: float | None = None,
) -> Any:
    """A documented message field.

    Args:
        doc: what the field means.
        unit: its unit (SI on the bus: m, rad, s, m/s, rad/s; ``ns`` for stamps).
        default: default value.
        default_factory: default factory (for lists).
        length: required length of a list field (or of each row of a list of lists).
        choices: allowed values of a ``str`` field: a tuple, or a ``StrEnum`` class (its
            members' values); checked when the message is built and when it is decoded.
        minimum: smallest allowed numeric value.
        maximum: largest allowed numeric value.
    """
    if isinstance(choices, type):
        choices = tuple(member.value for member in choices)
    meta = {
        "doc": doc,
        "unit": unit,
        "length": length,
        "choices": choices,
        "minimum": minimum,
        "maximum": maximum,
    }
    if default_factory is not dataclasses.MISSING:
        return dataclasses.field(default_factory=default_factory, metadata=meta)
    return dataclasses.field(default=default, metadata=meta)


class Message:
    """Base of every bus message (subclasses are frozen dataclasses)."""

    TYPE_NAME: ClassVar[str] = ""
    """Stable, versioned name of the message type, e.g. ``manus/JointState/1``."""

    def __post_init__(self) -> None:
        """Check the fields with ``choices`` (built or decoded alike).

        Raises:
            SchemaError: naming the type, the field, the value and the allowed values.
        """
        for name, allowed in _choice_fields(type(self)):
            value = getattr(self, name)
            if value not in allowed:
                raise SchemaError(
                    f"{self.TYPE_NAME or type(self).__name__}.{name}: {value!r} is not one of "
                    f"{sorted(allowed)}"
                )

    def to_dict(self) -> dict[str, Any]:
        """Plain dict of plain values (lists, dicts, numbers, strings, bytes)."""
        out: dict[str, Any] = {}
        for name in _field_names(type(self)):
            value = getattr(self, name)
            kind = type(value)
            # Scalars first: most fields are, and messages are encoded every cycle.
            out[name] = value if kind in _SCALARS or value is None else _plain(value)
        return out

    def encode(self) -> bytes:
        """MessagePack bytes of :meth:`to_dict`."""
        return bytes(msgpack.packb(self.to_dict(), use_bin_type=True))

    @classmethod
    def from_dict(cls, data: Any) -> Self:
        """Validate ``data`` and build the message.

        Raises:
            SchemaError: naming the type, the field path, the value and what is allowed.
        """
        return _build(cls, data, cls.TYPE_NAME or cls.__name__)

    @classmethod
    def decode(cls, payload: bytes | bytearray | memoryview) -> Self:
        """Decode and validate a MessagePack payload.

        Raises:
            SchemaError: the payload is not MessagePack or does not match the type.
        """
        try:
            data = msgpack.unpackb(bytes(payload), raw=False, strict_map_key=True)
        except (ValueError, msgpack.ExtraData, msgpack.FormatError, msgpack.StackError) as exc:
            raise SchemaError(
                f"{cls.TYPE_NAME or cls.__name__}: payload is not MessagePack: {exc}"
            ) from exc
        return cls.from_dict(data)

    @classmethod
    def schema_rules(cls) -> list[dict[str, Any]]:
        """JSON Schema rules of this type beyond its fields (``allOf``: e.g. which fields
        each kind of a command uses); none by default."""
        return []

    @classmethod
    def json_schema(cls) -> dict[str, Any]:
        """JSON Schema (draft 2020-12) of this message type."""
        schema = _object_schema(cls)
        schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
        schema["$id"] = cls.TYPE_NAME
        schema["title"] = cls.__name__
        return schema


_SCALARS = frozenset({float, int, str, bool, bytes})
_NAMES: dict[type, tuple[str, ...]] = {}


def _field_names(cls: type) -> tuple[str, ...]:
    names = _NAMES.get(cls)
    if names is None:
        names = _NAMES[cls] = tuple(f.name for f in dataclasses.fields(cls))
    return names


def _plain(value: Any) -> Any:
    if isinstance(value, Message):
        return value.to_dict()
    if isinstance(value, list | tuple):
        if all(type(v) is float or type(v) is int for v in value):
            return list(value)  # numeric rows, the bulk of trajectories: no recursion
        return [_plain(v) for v in value]
    return value


_CHOICES: dict[type, tuple[tuple[str, frozenset[str]], ...]] = {}


def _choice_fields(cls: type) -> tuple[tuple[str, frozenset[str]], ...]:
    """(field name, allowed values) of every field of ``cls`` with ``choices``, cached:
    messages are built every cycle, so the check must cost next to nothing."""
    found = _CHOICES.get(cls)
    if found is None:
        found = _CHOICES[cls] = tuple(
            (f.name, frozenset(f.metadata["choices"]))
            for f in dataclasses.fields(cls)
            if f.metadata.get("choices")
        )
    return found


_HINTS: dict[type, dict[str, Any]] = {}


def _hints(cls: type) -> dict[str, Any]:
    # Resolving string annotations dominated decoding time; a class's hints never change.
    hints = _HINTS.get(cls)
    if hints is None:
        hints = _HINTS[cls] = typing.get_type_hints(cls)
    return hints


def _build(cls: type[M], data: Any, path: str) -> M:
    if not isinstance(data, dict):
        raise SchemaError(f"{path}: expected a map, got {type(data).__name__}")
    hints = _hints(cls)
    kwargs: dict[str, Any] = {}
    known = set()
    for f in dataclasses.fields(cls):  # type: ignore[arg-type]
        known.add(f.name)
        fpath = f"{path}.{f.name}"
        if f.name not in data:
            if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
                raise SchemaError(f"{fpath}: missing required field")
            continue
        kwargs[f.name] = _convert(hints[f.name], data[f.name], fpath, f.metadata)
    extra = set(data) - known
    if extra:
        raise SchemaError(f"{path}: unknown field(s) {sorted(map(str, extra))}")
    return cls(**kwargs)


def _convert(tp: Any, value: Any, path: str, meta: Any) -> Any:
    origin = get_origin(tp)
    if origin in (types.UnionType, typing.Union):
        args = [a for a in get_args(tp) if a is not type(None)]
        if value is None:
            return None
        return _convert(args[0], value, path, meta)
    if origin is list:
        return _convert_list(tp, value, path, meta)
    if isinstance(tp, type) and issubclass(tp, Message):
        return _build(tp, value, path)
    scalar = _DECODERS.get(tp)
    if scalar is None:  # pragma: no cover
        raise SchemaError(f"{path}: unsupported field type {tp!r}")
    return scalar(value, path, meta)


def _convert_list(tp: Any, value: Any, path: str, meta: Any) -> list[Any]:
    (inner,) = get_args(tp)
    if not isinstance(value, list | tuple):
        raise SchemaError(f"{path}: expected a list, got {type(value).__name__}")
    length = meta.get("length") if meta else None
    if length is not None and get_origin(inner) is not list and len(value) != length:
        raise SchemaError(f"{path}: expected {length} values, got {len(value)}")
    # Fast paths for numeric rows and tables (trajectories, previews); anything they
    # do not accept goes through the item-by-item checks below, which name the item.
    if inner is float and _finite_floats_in_range(value, meta):
        return list(value)
    if (
        get_origin(inner) is list
        and get_args(inner) == (float,)
        and _float_table(value, meta, length)
    ):
        return [list(row) for row in value]
    return [_convert(inner, v, f"{path}[{i}]", meta) for i, v in enumerate(value)]


def _to_bool(value: Any, path: str, meta: Any) -> bool:
    if not isinstance(value, bool):
        raise SchemaError(f"{path}: expected a boolean, got {value!r}")
    return value


def _to_int(value: Any, path: str, meta: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, int):
        raise SchemaError(f"{path}: expected an integer, got {value!r}")
    _range(path, value, meta)
    return value


def _to_float(value: Any, path: str, meta: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise SchemaError(f"{path}: expected a number, got {value!r}")
    fv = float(value)
    if not math.isfinite(fv):
        raise SchemaError(f"{path}: expected a finite number, got {value!r}")
    _range(path, fv, meta)
    return fv


def _to_str(value: Any, path: str, meta: Any) -> str:
    if not isinstance(value, str):
        raise SchemaError(f"{path}: expected a string, got {value!r}")
    choices = meta.get("choices") if meta else None
    if choices and value not in choices:
        raise SchemaError(f"{path}: {value!r} is not one of {list(choices)}")
    return value


def _to_bytes(value: Any, path: str, meta: Any) -> bytes:
    if not isinstance(value, bytes | bytearray):
        raise SchemaError(f"{path}: expected bytes, got {type(value).__name__}")
    return bytes(value)


_DECODERS: dict[Any, Callable[[Any, str, Any], Any]] = {
    bool: _to_bool,
    int: _to_int,
    float: _to_float,
    str: _to_str,
    bytes: _to_bytes,
}
"""Decoder of each scalar field type: (value, field path, field metadata) -> value."""


def _finite_floats_in_range(values: list[Any] | tuple[Any, ...], meta: Any) -> bool:
    """True when every item is a finite ``float`` within the field's range (no error to
    report, so the per-item checks can be skipped: long numeric rows decode fast)."""
    if not values or not all(type(v) is float for v in values):
        return False
    if not math.isfinite(sum(values)):  # any inf or nan makes the sum non-finite
        return False
    lo, hi = (meta.get("minimum"), meta.get("maximum")) if meta else (None, None)
    return (lo is None or min(values) >= lo) and (hi is None or max(values) <= hi)


def _float_table(rows: list[Any] | tuple[Any, ...], meta: Any, length: int | None) -> bool:
    """True when every row is a list of ``length`` (if set) finite floats in range."""
    return all(
        isinstance(row, list | tuple)
        and (length is None or len(row) == length)
        and _finite_floats_in_range(row, meta)
        for row in rows
    )


def _range(path: str, value: float, meta: Any) -> None:
    if not meta:
        return
    lo, hi = meta.get("minimum"), meta.get("maximum")
    if lo is not None and value < lo:
        raise SchemaError(f"{path}: {value!r} is below the minimum {lo!r}")
    if hi is not None and value > hi:
        raise SchemaError(f"{path}: {value!r} is above the maximum {hi!r}")


def _object_schema(cls: type) -> dict[str, Any]:
    hints = _hints(cls)
    props: dict[str, Any] = {}
    required: list[str] = []
    for f in dataclasses.fields(cls):
        props[f.name] = _type_schema(hints[f.name], f.metadata)
        doc = f.metadata.get("doc", "")
        unit = f.metadata.get("unit", "")
        props[f.name]["description"] = f"{doc} [{unit}]" if unit else doc
        if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING:
            required.append(f.name)
    schema: dict[str, Any] = {
        "type": "object",
        "description": (cls.__doc__ or "").strip().split("\n\n")[0],
        "properties": props,
        "required": required,
        "additionalProperties": False,
    }
    rules = cls.schema_rules() if issubclass(cls, Message) else []
    if rules:
        schema["allOf"] = rules
    return schema


def _type_schema(tp: Any, meta: Any, *, top: bool = True) -> dict[str, Any]:
    origin = get_origin(tp)
    if origin in (types.UnionType, typing.Union):
        args = [a for a in get_args(tp) if a is not type(None)]
        return {"anyOf": [_type_schema(args[0], meta, top=top), {"type": "null"}]}
    if origin is list:
        (inner,) = get_args(tp)
        out: dict[str, Any] = {"type": "array", "items": _type_schema(inner, meta, top=False)}
        length = meta.get("length") if meta else None
        if length is not None and get_origin(inner) is not list:
            out["minItems"] = out["maxItems"] = length
        return out
    if isinstance(tp, type) and issubclass(tp, Message):
        return _object_schema(tp)
    simple = {bool: "boolean", int: "integer", float: "number", str: "string"}
    if tp in simple:
        out = {"type": simple[tp]}
        if meta:
            if meta.get("minimum") is not None:
                out["minimum"] = meta["minimum"]
            if meta.get("maximum") is not None:
                out["maximum"] = meta["maximum"]
            if tp is str and meta.get("choices"):
                out["enum"] = list(meta["choices"])
        return out
    if tp is bytes:
        # MessagePack bin; JSON exports carry it as base64.
        return {"type": "string", "contentEncoding": "base64"}
    raise SchemaError(f"unsupported field type {tp!r}")  # pragma: no cover
