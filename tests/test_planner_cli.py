"""``manus plan`` from the shell: the trajectory as JSON, or one error line and exit 1."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path as FilePath

import numpy as np
import pytest

from manus.config import DEFAULT_ARM
from manus.kinematics import fk

ROOT = FilePath(__file__).resolve().parent.parent
SQUARE = str(ROOT / "paths" / "thesis_square.txt")


def manus(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "manus_stack.cli", *args], capture_output=True, text=True, timeout=60
    )


def test_plan_prints_one_row_per_knot() -> None:
    run = manus("plan", SQUARE)
    assert run.returncode == 0, run.stderr
    out = json.loads(run.stdout)
    assert out["times_s"][:3] == [0.0, 0.8, 2.4] and len(out["times_s"]) == 17
    q = np.array(out["positions_deg"])
    assert q.shape == (17, 6) and np.array(out["velocities_deg_s"]).shape == (17, 6)
    assert q[0] == pytest.approx([0, 30, -30, 0, -60, 0])
    assert fk(np.radians(q[1]), DEFAULT_ARM)[:3, 3] * 1000 == pytest.approx(
        np.array(out["via_xyz_mm"][1]), abs=1e-3
    )
    assert out["via_xyz_mm"][1] == pytest.approx([207.846097, 155.0, 200.0], abs=1e-5)
    assert out["via_lines"][0] == 3
    assert "accelerations_deg_s2" not in out and "preview_xyz_mm" not in out


def test_plan_options() -> None:
    run = manus(
        "plan",
        SQUARE,
        "--quintic",
        "--preview",
        "--start-joints",
        "10",
        "30",
        "-30",
        "0",
        "-60",
        "0",
    )
    assert run.returncode == 0, run.stderr
    out = json.loads(run.stdout)
    assert out["interpolation"] == "quintic"
    assert out["start_deg"] == pytest.approx([10, 30, -30, 0, -60, 0])
    assert out["accelerations_deg_s2"][0] == [0.0] * 6
    assert len(out["preview_xyz_mm"]) == 321 and out["preview_dt_s"] == pytest.approx(0.06)


def test_speed_scaling_flag(tmp_path: FilePath) -> None:
    fast = tmp_path / "fast.txt"
    fast.write_text("0 0 0 0 0 0 0 0 0 0 0 0 0 0\n0 300 0 0 0 0 0 0 0 0 0 0 0.5 2\n")
    refused = manus("plan", str(fast))
    assert refused.returncode == 1 and refused.stdout == ""
    assert refused.stderr.count("\n") == 1
    assert refused.stderr.startswith(f"manus plan: error: between {fast} line 1 (via point 0)")
    assert "above its limit 50.0 deg/s" in refused.stderr
    run = manus("plan", str(fast), "--speed-scaling")
    assert run.returncode == 0, run.stderr
    out = json.loads(run.stdout)
    assert out["time_scale"] > 1.0 and out["times_s"][1] == pytest.approx(0.5 * out["time_scale"])
    assert "time stretched" in out["notes"][0]


@pytest.mark.parametrize(
    ("text", "words"),
    [
        ("0 0 0 0 0 0 0 0 0 0 0 0 0 0\n0 1 2 3\n", "bad.txt:2: via point 1: expected 14 columns"),
        ("", "bad.txt: no via points"),
        (
            "0 0 0 0 0 0 0 0 0 0 0 0 0 0\n3000 0 0 0 0 0 0 0 0 0 0 0 1 0\n",
            "bad.txt line 2 (via point 1): outside the workspace",
        ),
    ],
)
def test_errors_are_one_line_and_exit_1(tmp_path: FilePath, text: str, words: str) -> None:
    bad = tmp_path / "bad.txt"
    bad.write_text(text)
    run = manus("plan", str(bad))
    assert run.returncode == 1 and run.stdout == ""
    assert run.stderr.count("\n") == 1 and run.stderr.startswith("manus plan: error: ")
    assert words.replace("bad.txt", str(bad)) in run.stderr
