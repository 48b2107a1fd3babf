"""Every message type: MessagePack round trip, validation errors, JSON Schema."""

from __future__ import annotations

import dataclasses
import typing
from typing import Any

import jsonschema
import msgpack
import pytest

from manus.errors import SchemaError
from schemas import endpoints as ep
from schemas.base import Message
from schemas.jog import JogCommand
from schemas.keys import Keys, channel_types
from schemas.planning import Path, PlanRequest, ViaPoint, ViaPointPath
from schemas.state import JointState

TYPES = sorted({t for t in channel_types().values()}, key=lambda t: t.TYPE_NAME)


RULED: dict[type[Message], Message] = {
    JogCommand: JogCommand(
        stamp_ns=1,
        seq=1,
        source="t",
        kind="twist",
        units="si",
        frame="gripper",
        linear=[0.1, 0.0, 0.0],
        angular=[0.0, 0.0, 0.2],
        gripper=0.01,
        drink=True,
        pour=0.1,
    ),
}
"""Examples of the types whose fields depend on each other (``schema_rules``)."""


def example(cls: type[Message]) -> Message:
    """A valid instance of ``cls`` with every field set (nested types recursively)."""
    if cls in RULED:
        return RULED[cls]
    hints = typing.get_type_hints(cls)
    kwargs: dict[str, Any] = {}
    for f in dataclasses.fields(cls):  # type: ignore[arg-type]
        kwargs[f.name] = _value(hints[f.name], f.metadata)
    return cls(**kwargs)


def _value(tp: Any, meta: Any) -> Any:
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin in (typing.Union, __import__("types").UnionType):
        return _value(next(a for a in args if a is not type(None)), meta)
    if origin is list:
        n = meta.get("length") or 2
        return [_value(args[0], meta) for _ in range(n)]
    if isinstance(tp, type) and issubclass(tp, Message):
        union = meta.get("union") if meta else None
        return example(tp if union is None else next(iter(union.members.values())))
    return _SCALAR_EXAMPLES[tp](meta or {})


def _float_example(meta: Any) -> float:
    lo = meta.get("minimum")
    return float(lo) if lo is not None else 0.5


_SCALAR_EXAMPLES: dict[Any, Any] = {
    bool: lambda meta: True,
    int: lambda meta: int(meta.get("minimum") or 0),
    float: _float_example,
    str: lambda meta: (meta.get("choices") or ["text"])[0],
    bytes: lambda meta: b"\x01\x02",
}
"""A valid example of each scalar field type, from the field's metadata."""


@pytest.mark.parametrize("cls", TYPES, ids=lambda t: t.TYPE_NAME)
def test_round_trip(cls: type[Message]) -> None:
    msg = example(cls)
    assert cls.decode(msg.encode()) == msg


@pytest.mark.parametrize("cls", TYPES, ids=lambda t: t.TYPE_NAME)
def test_json_schema_is_valid_and_accepts_the_example(cls: type[Message]) -> None:
    schema = cls.json_schema()
    jsonschema.Draft202012Validator.check_schema(schema)
    plain = msgpack.unpackb(example(cls).encode())
    plain = _bytes_to_text(plain)
    jsonschema.validate(plain, schema)


def _bytes_to_text(value: Any) -> Any:
    import base64

    if isinstance(value, bytes):
        return base64.b64encode(value).decode()
    if isinstance(value, dict):
        return {k: _bytes_to_text(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_bytes_to_text(v) for v in value]
    return value


def test_type_names_are_unique_and_versioned() -> None:
    names = [t.TYPE_NAME for t in TYPES]
    assert len(names) == len(set(names))
    assert all(n.startswith("manus/") and n.rsplit("/", 1)[1].isdigit() for n in names)


def joint_state(**changes: Any) -> dict[str, Any]:
    base = example(JointState).to_dict()
    base.update(changes)
    return base


@pytest.mark.parametrize(
    ("changes", "match"),
    [
        ({"position": [0.0] * 5}, r"JointState/2.position: expected 6 values, got 5"),
        ({"gripper": "wide"}, r"JointState/2.gripper: expected a number, got 'wide'"),
        ({"seq": -1}, r"JointState/2.seq: -1 is below the minimum 0"),
        ({"mode": "dance"}, r"JointState/2.mode: 'dance' is not one of"),
        ({"valid": 1}, r"JointState/2.valid: expected a boolean"),
        ({"gripper": float("nan")}, r"expected a finite number"),
        ({"extra": 1}, r"unknown field\(s\) \['extra'\]"),
    ],
)
def test_bad_fields_are_named(changes: dict[str, Any], match: str) -> None:
    with pytest.raises(SchemaError, match=match):
        JointState.decode(msgpack.packb(joint_state(**changes)))


def test_missing_field_and_garbage_are_schema_errors() -> None:
    data = joint_state()
    del data["seq"]
    with pytest.raises(SchemaError, match=r"JointState/2.seq: missing required field"):
        JointState.decode(msgpack.packb(data))
    with pytest.raises(SchemaError, match="not MessagePack"):
        JointState.decode(b"\xc1\xc1\xc1")
    with pytest.raises(SchemaError, match="expected a map"):
        JointState.decode(msgpack.packb([1, 2, 3]))


def test_nested_errors_name_the_path() -> None:
    vp = example(ViaPoint).to_dict()
    vp["type"] = 7
    path = {"via_points": [example(ViaPoint).to_dict(), vp], "source": "x"}
    bad = {"motion": {"kind": "via_points", "path": path}}
    with pytest.raises(
        SchemaError,
        match=r"PlanRequest/2.motion.path.via_points\[1\].type: 7 is above the maximum 2",
    ):
        PlanRequest.decode(msgpack.packb(bad))
    assert PlanRequest.decode(PlanRequest(ViaPointPath(path=Path([]))).encode()).start is None


def test_keys_are_rooted_at_the_prefix() -> None:
    k = Keys("lab/arm2")
    assert k(ep.JOINTS) == "lab/arm2/state/joints"
    assert k.alive("controller") == "lab/arm2/alive/controller"
    assert k.suffix(k(ep.JOINTS)) == "state/joints"
