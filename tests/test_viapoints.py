"""Via-point files: the thesis format, its rules and one clear error per broken rule."""

from __future__ import annotations

import itertools
import math
from pathlib import Path as FilePath

import pytest
from hypothesis import given
from hypothesis import strategies as st

from manus.errors import ManusError
from manus.viapoints import (
    COLUMNS,
    ViaPointError,
    format_path,
    load_path,
    parse_viapoints,
    path_from_rows,
    path_to_rows,
    validate_path,
)
from schemas.planning import Path, ViaPoint

ROOT = FilePath(__file__).resolve().parent.parent
ZERO_ROW = "0 0 0 0 0 0 0 0 0 0 0 0 0 0"


def test_thesis_square_parses_in_si_units_with_lines() -> None:
    path = load_path(ROOT / "paths" / "thesis_square.txt")
    assert len(path.via_points) == 17
    assert path.source.endswith("thesis_square.txt")
    first, second = path.via_points[0], path.via_points[1]
    assert first.line == 3  # two comment lines above it
    assert second.xyz == pytest.approx([0.0, 0.05, 0.0])
    assert second.time == 0.8 and second.type == 2
    assert path.via_points[-1].time == pytest.approx(19.2)
    assert [vp.line for vp in path.via_points] == list(range(3, 20))


def test_thesis_circle_parses() -> None:
    path = load_path(ROOT / "paths" / "thesis_circle.txt")
    assert len(path.via_points) == 19
    assert path.via_points[-1].time == pytest.approx(25.2)
    total = [sum(vp.xyz[k] for vp in path.via_points[1:]) for k in range(3)]
    assert total == pytest.approx([0.0, 0.0, 0.0], abs=1e-9)  # the circle closes


def test_columns_map_to_message_fields_and_units() -> None:
    text = f"{ZERO_ROW}\n1 2 3  4 5 6  10 20 30  1 2 3  1.5 0\n"
    vp = parse_viapoints(text).via_points[1]
    assert vp.xyz == pytest.approx([0.001, 0.002, 0.003])
    assert vp.velocity == pytest.approx([0.004, 0.005, 0.006])
    # File order is yaw ROLL pitch; the message keeps (yaw, pitch, roll).
    assert vp.ypr == pytest.approx([math.radians(10), math.radians(30), math.radians(20)])
    assert vp.angular_velocity == pytest.approx([math.radians(1), math.radians(3), math.radians(2)])
    assert vp.time == 1.5 and vp.type == 0 and vp.line == 2


def test_comments_blank_lines_crlf_and_bom() -> None:
    text = (
        "\ufeff# header\r\n\r\n"
        f"{ZERO_ROW}   # the start\r\n"
        "   \t\n"
        "0 50 0 0 0 0 0 0 0 0 0 0 0.8 2#no space before the comment\n"
    )
    path = parse_viapoints(text, "x.txt")
    assert [vp.line for vp in path.via_points] == [3, 5]
    assert path.via_points[1].xyz == pytest.approx([0.0, 0.05, 0.0])


def _error(text: str) -> ViaPointError:
    with pytest.raises(ViaPointError) as info:
        parse_viapoints(text, "bad.txt")
    assert isinstance(info.value, ManusError)
    assert "\n" not in str(info.value)
    return info.value


@pytest.mark.parametrize(
    ("text", "line", "column", "words"),
    [
        (f"{ZERO_ROW}\n0 50 0 0 0 0 0 0 0 0 0 0 0.8\n", 2, "", "expected 14 columns"),
        (f"{ZERO_ROW}\n0 50 0 0 0 0 0 0 0 0 0 0 0.8 2 7\n", 2, "", "got 15"),
        (f"{ZERO_ROW}\n0 5O 0 0 0 0 0 0 0 0 0 0 0.8 2\n", 2, "Y", "not a number"),
        (f"{ZERO_ROW}\n0 1,5 0 0 0 0 0 0 0 0 0 0 0.8 2\n", 2, "Y", "not a number"),
        (f"{ZERO_ROW}\n0 0 nan 0 0 0 0 0 0 0 0 0 0.8 2\n", 2, "Z", "not a finite number"),
        (f"{ZERO_ROW}\n0 0 0 0 0 0 -inf 0 0 0 0 0 0.8 2\n", 2, "Yaw", "not a finite number"),
        (f"{ZERO_ROW}\n0 0 0 0 0 0 0 0 1e999 0 0 0 0.8 2\n", 2, "Pitch", "too large"),
        (f"{ZERO_ROW}\n0 0 0 0 0 0 0 0 0 0 0 0 0 2\n", 2, "time", "after the previous"),
        (
            f"{ZERO_ROW}\n1 0 0 0 0 0 0 0 0 0 0 0 2 2\n1 0 0 0 0 0 0 0 0 0 0 0 1 2\n",
            3,
            "time",
            "strictly increasing",
        ),
        ("0 0 0 0 0 0 0 0 0 0 0 0 0.5 0\n" + ZERO_ROW, 1, "time", "must be 0"),
        (f"{ZERO_ROW}\n0 0 0 0 0 0 0 0 0 0 0 0 1 3\n", 2, "type", "unknown type"),
        (f"{ZERO_ROW}\n0 0 0 0 0 0 0 0 0 0 0 0 1 1.5\n", 2, "type", "unknown type"),
        (f"{ZERO_ROW}\n0 0 0 0 0 0 0 0 0 0 0 0 -1 2\n", 2, "time", "negative"),
        (f"{ZERO_ROW}\n20000 0 0 0 0 0 0 0 0 0 0 0 1 2\n", 2, "X", "at most 10000 mm"),
        (f"{ZERO_ROW}\n0 0 0 0 0 -1e5 0 0 0 0 0 0 1 2\n", 2, "Vz", "at most 10000 mm/s"),
        (f"{ZERO_ROW}\n0 0 0 0 0 0 0 7200 0 0 0 0 1 2\n", 2, "Roll", "at most 3600 deg"),
        (f"{ZERO_ROW}\n0 0 0 0 0 0 0 0 0 0 0 0 1e6 2\n", 2, "time", "at most 86400 s"),
        ("", 0, "", "no via points"),
        ("# only a comment\n\n", 0, "", "no via points"),
        (f"# start only\n{ZERO_ROW}\n", 2, "", "at least two via points"),
    ],
)
def test_each_broken_rule_gives_one_clear_error(
    text: str, line: int, column: str, words: str
) -> None:
    err = _error(text)
    assert words in err.rule
    assert err.source == "bad.txt"
    assert err.line == line
    assert err.column == column
    assert str(err).startswith(f"bad.txt:{line}" if line else "bad.txt")
    if column:
        assert f"column {column} = " in str(err)


def test_error_names_the_offending_text() -> None:
    err = _error(f"{ZERO_ROW}\n0 5O 0 0 0 0 0 0 0 0 0 0 0.8 2\n")
    assert err.value == "5O"
    assert str(err) == (
        "bad.txt:2: via point 1: column Y = 5O: not a number (expected e.g. 12, -0.5, 1e-3)"
    )


def test_format_round_trips() -> None:
    path = load_path(ROOT / "paths" / "thesis_circle.txt")
    again = parse_viapoints(format_path(path), path.source)
    for a, b in zip(path.via_points, again.via_points, strict=True):
        assert a.xyz == pytest.approx(b.xyz, abs=1e-12)
        assert a.ypr == pytest.approx(b.ypr, abs=1e-12)
        assert (a.time, a.type) == (b.time, b.type)
    rows = path_to_rows(path)
    assert len(rows[0]) == len(COLUMNS)
    assert path_from_rows(rows, source="x").via_points[3].xyz == pytest.approx(
        path.via_points[3].xyz
    )


def test_path_from_rows_checks_the_same_rules() -> None:
    with pytest.raises(ViaPointError, match="rows:8: via point 1: column time"):
        path_from_rows([[0.0] * 14, [0.0] * 14], source="rows", lines=[7, 8])
    with pytest.raises(ViaPointError, match="expected 14 columns"):
        path_from_rows([[0.0] * 14, [0.0] * 13])


def test_validate_path_applies_the_rules_to_messages() -> None:
    vp = ViaPoint(xyz=[0.0] * 3, velocity=[0.0] * 3, ypr=[0.0] * 3,
                  angular_velocity=[0.0] * 3, time=0.0, type=0)  # fmt: skip
    good = Path(via_points=[vp, ViaPoint(**{**vp.to_dict(), "time": 1.0})], source="msg")
    validate_path(good)
    late_start = Path(via_points=[ViaPoint(**{**vp.to_dict(), "time": 1.0}), vp], source="msg")
    with pytest.raises(ViaPointError, match="msg: via point 0: column time = 1 s"):
        validate_path(late_start)
    far = ViaPoint(**{**vp.to_dict(), "time": 1.0, "xyz": [0.0, 11.0, 0.0]})
    with pytest.raises(ViaPointError, match="column Y = 11000 mm"):
        validate_path(Path(via_points=[vp, far]))


def test_load_path_reports_unreadable_files(tmp_path: FilePath) -> None:
    with pytest.raises(ViaPointError, match="cannot read the file"):
        load_path(tmp_path / "missing.txt")
    binary = tmp_path / "binary.txt"
    binary.write_bytes(f"{ZERO_ROW}\n".encode() + b"\xff\xfe\n")
    with pytest.raises(ViaPointError, match=r"binary.txt:2: not UTF-8 text \(byte 0xff\)"):
        load_path(binary)


TOKENS = st.sampled_from(
    ["0", "1", "2", "-3.5", "1e3", "1e999", "nan", "inf", "x", "#", "0.0", "2.5", "1e-9", "\t"]
)
LINES = st.lists(TOKENS, min_size=0, max_size=16).map(" ".join)


@given(st.text(max_size=300))
def test_random_text_never_raises_anything_else(text: str) -> None:
    try:
        path = parse_viapoints(text, "fuzz")
    except ViaPointError:
        return
    assert len(path.via_points) >= 2


@given(st.lists(LINES, max_size=6).map("\n".join))
def test_random_rows_never_raise_anything_else(text: str) -> None:
    try:
        path = parse_viapoints(text, "fuzz")
    except ViaPointError as exc:
        assert str(exc).startswith("fuzz")
        return
    times = [vp.time for vp in path.via_points]
    assert times[0] == 0.0 and all(b > a for a, b in itertools.pairwise(times))
