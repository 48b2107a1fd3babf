"""Reading YAML with positions: typed fields whose errors name the file, the line and
the field (``scene.yaml:8: objects[0].radius_mm: must be > 0, got -5``).

PyYAML's :func:`yaml.compose` gives the node tree with a mark (line, column) on every
node, which ``tomllib`` and ``json`` do not; :class:`FieldReader` walks it. LibYAML's
parser (:data:`LOADER`, in PyYAML's wheels) composes the same tree about ten times faster
than PyYAML's Python one, which is kept where LibYAML is missing.
"""

from __future__ import annotations

import math

import yaml

from manus.errors import ManusError

LOADER: type[yaml.SafeLoader] = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
"""The safe loader: LibYAML's where PyYAML has it."""


class FieldReader:
    """Walks the PyYAML node tree, converting values and naming positions in errors.

    Args:
        source: the file name errors start with.
        error: the exception type to raise (a :class:`ManusError`).
    """

    def __init__(self, source: str, error: type[ManusError]) -> None:
        self.source = source
        self.error = error

    def root(self, text: str, what: str) -> yaml.Node:
        """The node tree of YAML ``text``, the file of ``what`` ("scene", "poses", ...).

        Raises:
            ManusError: of the reader's type: not valid YAML (with its line), or empty.
        """
        try:
            root = yaml.compose(text, Loader=LOADER)
        except yaml.MarkedYAMLError as exc:
            mark = exc.problem_mark
            line = mark.line + 1 if mark is not None else 0
            raise self.error(f"{self.source}:{line}: not valid YAML: {exc.problem}") from exc
        if root is None:
            raise self.error(f"{self.source}: the {what} file is empty")
        return root

    def fail(self, node: yaml.Node | None, path: str, problem: str) -> ManusError:
        line = node.start_mark.line + 1 if node is not None else 0
        where = f"{self.source}:{line}" if line else self.source
        return self.error(f"{where}: {path}: {problem}" if path else f"{where}: {problem}")

    def mapping(
        self, node: yaml.Node, path: str, required: tuple[str, ...], optional: tuple[str, ...]
    ) -> dict[str, yaml.Node]:
        if not isinstance(node, yaml.MappingNode):
            raise self.fail(node, path, "must be a mapping (key: value lines)")
        out: dict[str, yaml.Node] = {}
        for key_node, value_node in node.value:
            key = str(key_node.value)
            if key not in required and key not in optional:
                allowed = ", ".join(required + optional)
                raise self.fail(key_node, join(path, key), f"unknown field (allowed: {allowed})")
            if key in out:
                raise self.fail(key_node, join(path, key), "given twice")
            out[key] = value_node
        for key in required:
            if key not in out:
                raise self.fail(node, join(path, key), "missing field")
        return out

    def number(
        self, node: yaml.Node, path: str, *, positive: bool = False, minimum: float | None = None
    ) -> float:
        if not isinstance(node, yaml.ScalarNode) or node.tag not in (
            "tag:yaml.org,2002:int",
            "tag:yaml.org,2002:float",
        ):
            raise self.fail(node, path, f"must be a number, got {node.value!r}")
        value = scalar_number(node)
        if not math.isfinite(value):
            raise self.fail(node, path, f"must be a finite number, got {node.value}")
        if positive and value <= 0.0:
            raise self.fail(node, path, f"must be > 0, got {node.value}")
        if minimum is not None and value < minimum:
            raise self.fail(node, path, f"must be >= {minimum:g}, got {node.value}")
        if abs(value) > 1e5:
            raise self.fail(node, path, f"must be within +-100000 (mm or deg), got {node.value}")
        return value

    def vector(
        self, node: yaml.Node, path: str, n: int = 3, *, positive: bool = False
    ) -> list[float]:
        if not isinstance(node, yaml.SequenceNode) or len(node.value) != n:
            raise self.fail(node, path, f"must be a list of {n} numbers")
        return [self.number(v, f"{path}[{i}]", positive=positive) for i, v in enumerate(node.value)]

    def text(self, node: yaml.Node, path: str, choices: tuple[str, ...] | None = None) -> str:
        if not isinstance(node, yaml.ScalarNode) or node.tag != "tag:yaml.org,2002:str":
            raise self.fail(node, path, f"must be a name, got {node.value!r}")
        value = str(node.value)
        if choices is not None and value not in choices:
            raise self.fail(node, path, f"unknown value {value!r} (allowed: {', '.join(choices)})")
        if choices is None and not value.replace("_", "").replace("-", "").isalnum():
            raise self.fail(node, path, f"names are letters, digits, _ and -, got {value!r}")
        return value

    def items(self, node: yaml.Node, path: str) -> list[yaml.Node]:
        if not isinstance(node, yaml.SequenceNode):
            raise self.fail(node, path, "must be a list (lines starting with -)")
        return list(node.value)


def scalar_number(node: yaml.ScalarNode) -> float:
    """The value of an int or float scalar, as YAML 1.1 spells them (.nan, .inf, 1_000)."""
    text = str(node.value).replace("_", "").lower()
    special = {".nan": math.nan, ".inf": math.inf, "+.inf": math.inf, "-.inf": -math.inf}
    if text in special:
        return special[text]
    try:
        return float(text)
    except ValueError:
        return float(int(text, 0))  # 0x.., 0o.. integers


def join(path: str, key: str) -> str:
    """``path.key`` (``key`` at the top)."""
    return f"{path}.{key}" if path else key
