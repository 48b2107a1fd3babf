"""Tagged unions (schemas/tagged.py): a field holding one of several messages by its tag."""

from __future__ import annotations

from dataclasses import dataclass

import jsonschema
import msgpack
import pytest

from manus.errors import SchemaError
from schemas.base import Message, field
from schemas.motion import MOTIONS, Motion
from schemas.planning import Path, PlanRequest, ViaPointPath
from schemas.tagged import TaggedUnion, tag


@dataclass(frozen=True)
class Shape(Message):
    """Base of the test union."""


SHAPES: TaggedUnion[Shape] = TaggedUnion(Shape)


@SHAPES.member
@dataclass(frozen=True)
class Circle(Shape):
    """A circle."""

    TYPE_NAME = "test/Circle/1"
    kind: str = tag("circle", "a circle")
    radius: float = field("its radius", unit="m", minimum=0.0)


@SHAPES.member
@dataclass(frozen=True)
class Square(Shape):
    """A square."""

    TYPE_NAME = "test/Square/1"
    kind: str = tag("square", "a square")
    side: float = field("its side", unit="m")
    label: str = field("a name", default="")


@dataclass(frozen=True)
class Drawing(Message):
    """Holds shapes."""

    TYPE_NAME = "test/Drawing/1"
    shape: Shape = field("the main shape", union=SHAPES)
    others: list[Shape] = field("more shapes", default_factory=list, union=SHAPES)
    spare: Shape | None = field("maybe one more", default=None, union=SHAPES)


def test_members_round_trip_by_their_tag_in_every_kind_of_field() -> None:
    msg = Drawing(
        shape=Square(side=0.2),
        others=[Circle(radius=1.0), Square(side=3.0)],
        spare=Circle(radius=0.5),
    )
    plain = msg.to_dict()
    assert plain["shape"] == {"kind": "square", "side": 0.2, "label": ""}
    assert plain["others"][0]["kind"] == "circle"
    assert Drawing.decode(msg.encode()) == msg
    assert Drawing.decode(Drawing(shape=Circle(radius=2.0)).encode()).spare is None


def test_a_missing_or_unknown_tag_names_the_field_and_the_kinds() -> None:
    with pytest.raises(
        SchemaError, match=r"Drawing/1.shape.kind: missing .*\['circle', 'square'\]"
    ):
        Drawing.decode(msgpack.packb({"shape": {"radius": 1.0}}))
    with pytest.raises(SchemaError, match=r"shape.kind: 'triangle' is not one of \['circle'"):
        Drawing.decode(msgpack.packb({"shape": {"kind": "triangle", "radius": 1.0}}))
    with pytest.raises(SchemaError, match=r"others\[1\].kind: 7 is not one of"):
        Drawing.decode(msgpack.packb({"shape": {"kind": "circle", "radius": 1.0},
                                      "others": [{"kind": "square", "side": 1.0},
                                                 {"kind": 7}]}))  # fmt: skip
    with pytest.raises(SchemaError, match=r"shape.radius: -1.0 is below the minimum 0.0"):
        Drawing.decode(msgpack.packb({"shape": {"kind": "circle", "radius": -1.0}}))
    with pytest.raises(SchemaError, match=r"shape: unknown field\(s\) \['side'\]"):
        Drawing.decode(msgpack.packb({"shape": {"kind": "circle", "radius": 1.0, "side": 2}}))


def test_only_members_may_be_built_into_the_field_and_a_tag_is_fixed() -> None:
    with pytest.raises(
        SchemaError, match=r"Drawing/1.shape: a Shape is not a member of the Shape union \("
    ):
        Drawing(shape=Shape())
    with pytest.raises(SchemaError, match=r"Drawing/1.others: a Shape is not a member"):
        Drawing(shape=Circle(radius=1.0), others=[Circle(radius=2.0), Shape()])
    with pytest.raises(SchemaError, match=r"Circle/1.kind: 'square' is not one of \['circle'\]"):
        Circle(radius=1.0, kind="square")


def test_a_member_needs_the_base_a_tag_of_its_own_and_a_free_value() -> None:
    union: TaggedUnion[Shape] = TaggedUnion(Shape)
    with pytest.raises(SchemaError, match="is not a Shape"):
        union.member(ViaPointPath)

    @dataclass(frozen=True)
    class Untagged(Shape):
        size: float = field("size")

    with pytest.raises(SchemaError, match="needs a `kind` field made by tag"):
        union.member(Untagged)
    union.member(Circle)

    @dataclass(frozen=True)
    class Ring(Shape):
        kind: str = tag("circle", "a ring")

    with pytest.raises(SchemaError, match="kind 'circle' is taken by Circle"):
        union.member(Ring)


def test_json_schema_is_one_of_the_members_by_their_tag() -> None:
    schema = Drawing.json_schema()
    jsonschema.Draft202012Validator.check_schema(schema)
    shape = schema["properties"]["shape"]
    assert shape["discriminator"] == {"propertyName": "kind"}
    assert [v["properties"]["kind"]["const"] for v in shape["oneOf"]] == ["circle", "square"]
    assert all(v["required"][0] == "kind" for v in shape["oneOf"])
    for good in ({"kind": "circle", "radius": 1.0}, {"kind": "square", "side": 1.0}):
        jsonschema.validate({"shape": good}, schema)
    for bad in ({"radius": 1.0}, {"kind": "circle", "side": 1.0}, {"kind": "hexagon"}):
        with pytest.raises(jsonschema.ValidationError):
            jsonschema.validate({"shape": bad}, schema)


def test_the_plan_request_declares_only_the_kinds_served() -> None:
    served = ["continuation", "joints", "line", "named", "object", "pose", "via_points"]
    assert sorted(MOTIONS.kinds()) == served
    schema = PlanRequest.json_schema()
    assert schema["$id"] == "manus/PlanRequest/2"
    motion = schema["properties"]["motion"]
    assert sorted(v["title"] for v in motion["oneOf"]) == [
        "JointGoal",
        "LineMotion",
        "NamedGoal",
        "ObjectGoal",
        "PoseGoal",
        "ViaPointContinuation",
        "ViaPointPath",
    ]
    request = PlanRequest(ViaPointPath(path=Path(via_points=[])), start=[0.0] * 6)
    jsonschema.validate(msgpack.unpackb(request.encode()), schema)
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate({"motion": {"kind": "teleport", "goal": [0.0] * 6}}, schema)
    with pytest.raises(SchemaError, match=r"motion.kind: 'teleport' is not one of \["):
        PlanRequest.decode(msgpack.packb({"motion": {"kind": "teleport", "goal": [0.0] * 6}}))
    with pytest.raises(SchemaError, match="a Motion is not a member"):
        PlanRequest(Motion())
