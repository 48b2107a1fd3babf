"""The message machinery: typed dataclasses <-> MessagePack, validated, with JSON Schema.

Every bus message is a frozen dataclass deriving from :class:`Message`. Each field
carries its documentation and unit in its metadata (use :func:`field`), and that one
definition gives the MessagePack codec (:meth:`Message.encode` / :meth:`Message.decode`,
validated on decode) and the language-neutral JSON Schema (:meth:`Message.json_schema`).

Supported field types: ``int``, ``float``, ``bool``, ``str``, ``bytes``, a nested
``Message``, ``list[T]`` of any of these, and ``T | None``. A nested field may hold one of
several message types told apart by a tag field (``field(..., union=...)``: a
:class:`schemas.tagged.TaggedUnion`).

A ``str`` field with ``choices`` (a tuple, or a ``StrEnum`` class whose members are the
allowed values: the typed states of :mod:`schemas.states`; for a ``list[str]`` field, of
each item) is checked when a message is built, not only when it is decoded:
``GoalResult(status="preemted", ...)`` raises a :class:`~manus.errors.SchemaError` naming
the field and the allowed values. So is the kind of a union field's value.
"""

from __future__ import annotations

import dataclasses
import enum
import types
import typing
from typing import Any, ClassVar, Protocol, Self, TypeVar, get_args, get_origin

import msgpack

from manus.errors import SchemaError
from schemas.scalars import DECODERS, finite_floats_in_range, float_table, ints_in_range, strings

M = TypeVar("M", bound="Message")


class UnionCodec(Protocol):
    """What a union field needs of its union (:class:`schemas.tagged.TaggedUnion`)."""

    def decode(self, data: Any, path: str) -> Message:
        """The member ``data`` names, built from it (errors name ``path``)."""
        ...

    def check(self, value: object, where: str) -> None:
        """Raise :class:`SchemaError` unless ``value`` is an instance of a member."""
        ...

    def json_schema(self) -> dict[str, Any]:
        """JSON Schema of the field: one of the members, by the tag."""
        ...


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
    union: UnionCodec | None = None,
    kw_only: bool = False,
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
        union: for a nested message field, the members it may hold, told apart by their
            tag (:class:`schemas.tagged.TaggedUnion`).
        kw_only: a keyword-only argument of the constructor (a field with a default
            before fields without one: a union member's tag).
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
        "union": union,
    }
    extra: dict[str, Any] = {"kw_only": True} if kw_only else {}
    if default_factory is not dataclasses.MISSING:
        return dataclasses.field(default_factory=default_factory, metadata=meta, **extra)
    return dataclasses.field(default=default, metadata=meta, **extra)


class Message:
    """Base of every bus message (subclasses are frozen dataclasses)."""

    TYPE_NAME: ClassVar[str] = ""
    """Stable, versioned name of the message type, e.g. ``manus/JointState/1``."""

    def __post_init__(self) -> None:
        """Check the fields with ``choices`` and the union fields (built or decoded alike).

        Raises:
            SchemaError: naming the type, the field, the value and the allowed values.
        """
        cls = type(self)
        for name, allowed in _choice_fields(cls):
            value = getattr(self, name)
            for item in value if type(value) is list else (value,):
                if item not in allowed:
                    raise SchemaError(
                        f"{self.TYPE_NAME or cls.__name__}.{name}: {item!r} is not one of "
                        f"{sorted(allowed)}"
                    )
        for name, union in _union_fields(cls):
            value = getattr(self, name)
            for item in value if type(value) is list else (value,):
                if item is not None:
                    union.check(item, f"{self.TYPE_NAME or cls.__name__}.{name}")

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
    def from_dict(cls, data: Any, path: str = "") -> Self:
        """Validate ``data`` and build the message.

        Args:
            data: the plain values (a map).
            path: how errors name it (default: the type's name; a field path when it is
                nested).

        Raises:
            SchemaError: naming the type, the field path, the value and what is allowed.
        """
        return _build(cls, data, path or cls.TYPE_NAME or cls.__name__)

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
        if all(type(v) is str for v in value):
            return list(value)
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


_UNIONS: dict[type, tuple[tuple[str, UnionCodec], ...]] = {}


def _union_fields(cls: type) -> tuple[tuple[str, UnionCodec], ...]:
    """(field name, union) of every union field of ``cls``, cached as :func:`_choice_fields`."""
    found = _UNIONS.get(cls)
    if found is None:
        found = _UNIONS[cls] = tuple(
            (f.name, f.metadata["union"])
            for f in dataclasses.fields(cls)
            if f.metadata.get("union") is not None
        )
    return found


_HINTS: dict[type, dict[str, Any]] = {}


def _hints(cls: type) -> dict[str, Any]:
    # Resolving string annotations dominated decoding time; a class's hints never change.
    hints = _HINTS.get(cls)
    if hints is None:
        hints = _HINTS[cls] = typing.get_type_hints(cls)
    return hints


_FIELDS: dict[type, tuple[tuple[str, Any, bool, Any], ...]] = {}


def _decoded_fields(cls: type) -> tuple[tuple[str, Any, bool, Any], ...]:
    """(name, type, required, metadata) of each field of ``cls``, cached (decoding time)."""
    found = _FIELDS.get(cls)
    if found is None:
        hints = _hints(cls)
        found = _FIELDS[cls] = tuple(
            (
                f.name,
                hints[f.name],
                f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING,
                f.metadata,
            )
            for f in dataclasses.fields(cls)
        )
    return found


_SHAPES: dict[Any, tuple[Any, tuple[Any, ...]]] = {}


def _shape(tp: Any) -> tuple[Any, tuple[Any, ...]]:
    """``(get_origin(tp), get_args(tp))``, cached: the typing calls dominated decoding."""
    found = _SHAPES.get(tp)
    if found is None:
        found = _SHAPES[tp] = (get_origin(tp), get_args(tp))
    return found


def _build(cls: type[M], data: Any, path: str) -> M:
    if not isinstance(data, dict):
        raise SchemaError(f"{path}: expected a map, got {type(data).__name__}")
    kwargs: dict[str, Any] = {}
    fields = _decoded_fields(cls)
    for name, tp, required, meta in fields:
        if name not in data:
            if required:
                raise SchemaError(f"{path}.{name}: missing required field")
            continue
        kwargs[name] = _convert(tp, data[name], f"{path}.{name}", meta)
    if len(kwargs) != len(data):
        extra = set(data) - {name for name, *_ in fields}
        raise SchemaError(f"{path}: unknown field(s) {sorted(map(str, extra))}")
    return cls(**kwargs)


def _convert(tp: Any, value: Any, path: str, meta: Any) -> Any:
    origin, args = _shape(tp)
    if origin in (types.UnionType, typing.Union):
        if value is None:
            return None
        return _convert(next(a for a in args if a is not type(None)), value, path, meta)
    if origin is list:
        return _convert_list(tp, value, path, meta)
    if isinstance(tp, type) and issubclass(tp, Message):
        union = meta.get("union") if meta else None
        return _build(tp, value, path) if union is None else union.decode(value, path)
    scalar = DECODERS.get(tp)
    if scalar is None:  # pragma: no cover
        raise SchemaError(f"{path}: unsupported field type {tp!r}")
    return scalar(value, path, meta)


def _convert_list(tp: Any, value: Any, path: str, meta: Any) -> list[Any]:
    (inner,) = _shape(tp)[1]
    if not isinstance(value, list | tuple):
        raise SchemaError(f"{path}: expected a list, got {type(value).__name__}")
    length = meta.get("length") if meta else None
    inner_origin, inner_args = _shape(inner)
    if length is not None and inner_origin is not list and len(value) != length:
        raise SchemaError(f"{path}: expected {length} values, got {len(value)}")
    # Fast paths for numeric rows and tables (trajectories, previews), integers and
    # strings; anything they do not accept goes through the item-by-item checks below,
    # which name the item.
    if inner is float and finite_floats_in_range(value, meta):
        return list(value)
    if inner_origin is list and inner_args == (float,) and float_table(value, meta, length):
        return [list(row) for row in value]
    if (inner is int and ints_in_range(value, meta)) or (inner is str and strings(value, meta)):
        return list(value)
    return [_convert(inner, v, f"{path}[{i}]", meta) for i, v in enumerate(value)]


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
        union = meta.get("union") if meta else None
        return _object_schema(tp) if union is None else union.json_schema()
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
