"""Decoders of the scalar field types: a payload's value -> the field's value, checked.

Each takes (value, field path, field metadata) and returns the value or raises a
:class:`~manus.errors.SchemaError` naming the path, the value and what is allowed (type,
``minimum``/``maximum``, ``choices``). The fast checks of numeric rows and tables let
:mod:`schemas.base` decode long trajectories without a call per number.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from manus.errors import SchemaError


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


DECODERS: dict[Any, Callable[[Any, str, Any], Any]] = {
    bool: _to_bool,
    int: _to_int,
    float: _to_float,
    str: _to_str,
    bytes: _to_bytes,
}
"""Decoder of each scalar field type: (value, field path, field metadata) -> value."""


def finite_floats_in_range(values: list[Any] | tuple[Any, ...], meta: Any) -> bool:
    """True when every item is a finite ``float`` within the field's range (no error to
    report, so the per-item checks can be skipped: long numeric rows decode fast)."""
    if not values or not all(type(v) is float for v in values):
        return False
    if not math.isfinite(sum(values)):  # any inf or nan makes the sum non-finite
        return False
    lo, hi = (meta.get("minimum"), meta.get("maximum")) if meta else (None, None)
    return (lo is None or min(values) >= lo) and (hi is None or max(values) <= hi)


def float_table(rows: list[Any] | tuple[Any, ...], meta: Any, length: int | None) -> bool:
    """True when every row is a list of ``length`` (if set) finite floats in range."""
    return all(
        isinstance(row, list | tuple)
        and (length is None or len(row) == length)
        and finite_floats_in_range(row, meta)
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


def ints_in_range(values: list[Any] | tuple[Any, ...], meta: Any) -> bool:
    """True when every item is an ``int`` (not a ``bool``) within the field's range."""
    if not all(type(v) is int for v in values):
        return False
    lo, hi = (meta.get("minimum"), meta.get("maximum")) if meta else (None, None)
    return not values or ((lo is None or min(values) >= lo) and (hi is None or max(values) <= hi))


def strings(values: list[Any] | tuple[Any, ...], meta: Any) -> bool:
    """True when every item is a ``str`` among the field's ``choices`` (if it has any)."""
    choices = meta.get("choices") if meta else None
    if choices:
        return all(type(v) is str and v in choices for v in values)
    return all(type(v) is str for v in values)
