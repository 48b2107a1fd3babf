"""``manus kin`` from the shell: JSON out, one-line errors, non-zero exit."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from manus.config import DEFAULT_ARM
from manus.kinematics import fk


def manus(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "manus_stack.cli", *args], capture_output=True, text=True, timeout=60
    )


def test_fk_prints_pose_json() -> None:
    run = manus("kin", "fk", "0", "30", "-30", "0", "-60", "0")
    assert run.returncode == 0, run.stderr
    out = json.loads(run.stdout)
    assert out["xyz_mm"] == pytest.approx([207.846097, 105.0, 200.0])
    assert out["ypr_deg"] == pytest.approx([0.0, -60.0, 0.0])
    T = np.array(out["matrix"])
    expected = fk(np.radians([0, 30, -30, 0, -60, 0]), DEFAULT_ARM)
    assert T[:3, :3] == pytest.approx(expected[:3, :3], abs=1e-8)


def test_ik_prints_all_branches_and_the_nearest() -> None:
    # The command line's pose order: X Y Z YAW PITCH ROLL.
    run = manus("kin", "ik", "207.846097", "105", "200", "0", "-60", "0")
    assert run.returncode == 0, run.stderr
    out = json.loads(run.stdout)
    assert len(out["solutions_deg"]) == 8
    assert out["nearest_deg"] == pytest.approx([0, 30, -30, 0, -60, 0], abs=1e-4)
    for q in out["solutions_deg"]:
        assert fk(np.radians(q), DEFAULT_ARM)[:3, 3] * 1000 == pytest.approx(
            [207.846097, 105, 200], abs=1e-3
        )


def test_ik_near_selects_another_branch() -> None:
    run = manus(
        "kin",
        "ik",
        "207.846097",
        "105",
        "200",
        "0",
        "-60",
        "0",
        "--near",
        "-146",
        "150",
        "-150",
        "-34",
        "60",
        "-180",
    )
    out = json.loads(run.stdout)
    assert out["nearest_deg"][0] == pytest.approx(-146.27, abs=0.01)


def test_fk_output_pastes_into_ik() -> None:
    # A pose with yaw, pitch and roll all different: fk's numbers, in the order it
    # prints them, are ik's arguments and give back the same joints.
    q = [10.0, 40.0, -20.0, 25.0, -50.0, 35.0]
    fk_run = manus("kin", "fk", *map(str, q))
    out = json.loads(fk_run.stdout)
    assert out["pose"] == out["xyz_mm"] + out["ypr_deg"]
    args = [repr(v) for v in out["xyz_mm"] + out["ypr_deg"]]
    ik_run = manus("kin", "ik", *args, "--near", *map(str, q))
    assert ik_run.returncode == 0, ik_run.stderr
    assert json.loads(ik_run.stdout)["nearest_deg"] == pytest.approx(q, abs=1e-3)


def test_ik_refuses_a_pose_that_is_not_a_number() -> None:
    run = manus("kin", "ik", "500", "0", "0", "nan", "0", "0")
    assert run.returncode == 2 and "argument YAW: must be a finite number" in run.stderr


def test_unreachable_pose_is_one_line_and_non_zero() -> None:
    run = manus("kin", "ik", "2000", "0", "0", "0", "0", "0")
    assert run.returncode != 0
    assert run.stdout == ""
    lines = run.stderr.strip().splitlines()
    assert len(lines) == 1 and "unreachable" in lines[0] and "2000.0" in lines[0]


def test_bad_number_is_an_argparse_error() -> None:
    run = manus("kin", "fk", "0", "30", "x", "0", "0", "0")
    assert run.returncode == 2 and "invalid float value: 'x'" in run.stderr
