"""Tagged unions: a message field that holds one of several message types, named by a tag.

A union has a base message class and its members, subclasses of it, each carrying the tag
field (``kind`` by default) with its own fixed value (:func:`tag`)::

    MOTIONS: TaggedUnion[Motion] = TaggedUnion(Motion)

    @MOTIONS.member
    @dataclass(frozen=True)
    class ViaPointPath(Motion):
        kind: str = tag("via_points", "a path of via points")
        path: Path = field("the path")

    motion: Motion = field("what to plan", union=MOTIONS)   # in the message that holds it

On the bus a member is an ordinary map with its tag among its fields; decoding reads the
tag first and builds that member (an unknown or missing tag is a
:class:`~manus.errors.SchemaError` naming the field and the kinds there are). Its JSON
Schema is a ``oneOf`` of the members, each with the tag as a required ``const``, plus
``discriminator: {propertyName: <tag>}`` for generators that use it (OpenAPI style; a
2020-12 validator takes it as an annotation). A member is one class and its decorator:
nothing else lists the members.
"""

from __future__ import annotations

import dataclasses
from typing import Any, Generic, TypeVar, cast

from manus.errors import SchemaError
from schemas.base import Message, field

B = TypeVar("B", bound=Message)
T = TypeVar("T", bound=Message)


def tag(value: str, doc: str) -> Any:
    """The tag field of a union member: always ``value`` (the default; any other value is
    refused when the message is built), keyword-only so that it may come first."""
    return field(doc, default=value, choices=(value,), kw_only=True)


class TaggedUnion(Generic[B]):
    """The members of a union field, by tag value.

    Args:
        base: the class every member derives from (the field's type).
        tag: the name of the tag field.
    """

    def __init__(self, base: type[B], tag: str = "kind") -> None:
        self.base = base
        self.tag = tag
        self.members: dict[str, type[B]] = {}
        """Member class of each tag value, in the order they were declared."""

    def member(self, cls: type[T]) -> type[T]:
        """Class decorator: declare ``cls`` a member (under its tag field's value).

        Raises:
            SchemaError: ``cls`` does not derive from the base, has no tag field with a
                string default, or its tag value is taken.
        """
        if self.base not in getattr(cls, "__mro__", ()):
            raise SchemaError(f"{cls!r} is not a {self.base.__name__}")
        member = cast(type[B], cls)  # checked just above (without narrowing cls itself)
        found = {f.name: f for f in dataclasses.fields(member)}.get(self.tag)  # type: ignore[arg-type]
        value = None if found is None else found.default
        if not isinstance(value, str) or not value:
            raise SchemaError(
                f"{cls.__name__}: a member of the {self.base.__name__} union needs a "
                f"`{self.tag}` field made by tag()"
            )
        if value in self.members:
            taken = self.members[value].__name__
            raise SchemaError(f"{cls.__name__}: {self.tag} {value!r} is taken by {taken}")
        self.members[value] = member
        return cls

    def kinds(self) -> list[str]:
        """The tag values, in declaration order."""
        return list(self.members)

    def decode(self, data: Any, path: str) -> B:
        """The member ``data`` names by its tag, built from ``data``.

        Raises:
            SchemaError: not a map, no tag, a tag that names no member, or a bad field.
        """
        if not isinstance(data, dict):
            raise SchemaError(f"{path}: expected a map, got {type(data).__name__}")
        if self.tag not in data:
            raise SchemaError(f"{path}.{self.tag}: missing required field: {self._allowed()}")
        value = data[self.tag]
        cls = self.members.get(value) if isinstance(value, str) else None
        if cls is None:
            raise SchemaError(f"{path}.{self.tag}: {value!r} is not {self._allowed()}")
        return cls.from_dict(data, path)

    def check(self, value: object, where: str) -> None:
        """Raise unless ``value`` is an instance of a member (when a message is built).

        Raises:
            SchemaError: naming ``where``, the value's type and the members.
        """
        if type(value) not in self.members.values():
            raise SchemaError(
                f"{where}: a {type(value).__name__} is not a member of the "
                f"{self.base.__name__} union ({', '.join(self.kinds())})"
            )

    def json_schema(self) -> dict[str, Any]:
        """``oneOf`` the members' schemas, each with its tag a required ``const``."""
        variants = []
        for value, cls in self.members.items():
            schema = cls.json_schema()
            for key in ("$schema", "$id"):  # a nested schema: no document of its own
                schema.pop(key, None)
            doc = schema["properties"][self.tag].get("description", "")
            schema["properties"][self.tag] = {"const": value, "description": doc}
            schema["required"] = [self.tag, *(r for r in schema["required"] if r != self.tag)]
            variants.append(schema)
        return {"oneOf": variants, "discriminator": {"propertyName": self.tag}}

    def _allowed(self) -> str:
        return f"one of {self.kinds()}"
