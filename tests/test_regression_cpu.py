"""Regression checks that mean the same on every CPU: a recording made as on an old
x86-64 CPU (NumPy's dispatch limited to its baseline, OpenBLAS on its Nehalem kernel,
glibc's libm without its FMA variants) checks with every feature of this CPU, and the
other way round; the float tolerance accepts rounding and nothing more."""

from __future__ import annotations

import dataclasses
import json
import math
import subprocess
import sys
from pathlib import Path

import pytest

from manus_stack.comparison import CPU_ROUNDING, EXACT, deviation, first_difference
from manus_stack.regression import check_planner
from schemas.base import Message
from schemas.planning import PlanReply
from services.recorder.reading import Recording, decode
from services.recorder.writer import RecordingWriter
from tests.cpu_dispatch import OLD_BLAS_KERNEL, baseline_env, native_env, runtime

SQUARE = Path(__file__).resolve().parent / "data" / "thesis_square.mcap"
SETTINGS = {"baseline": baseline_env, "native": native_env}
MARGIN = 1e-3
"""The rounding measured must stay this far below the tolerance (a tolerance far above
the rounding; a planner whose rounding grows towards it is worth a look)."""


def test_the_baseline_setting_takes_effect() -> None:
    found, kernel, libm = runtime(baseline_env())
    assert found == [], f"NumPy still dispatches to {found}"
    if kernel:  # OpenBLAS says which kernel it chose (x86-64)
        assert kernel == OLD_BLAS_KERNEL
    native, _, native_libm = runtime(native_env())
    # glibc's FMA variants: the same sums on a CPU without FMA, others on one with it
    print(f"CPU dispatch: native {native}, baseline {found} (OpenBLAS {kernel or '?'}); "
          f"libm {'the same' if libm == native_libm else 'other'} sums")  # fmt: skip


@pytest.fixture(scope="module")
def recordings(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """The thesis circle recorded in lock-step by ``manus_stack.recordings`` (the tool
    that makes tests/data) under each setting, in its own process."""
    made = {}
    for name, env in SETTINGS.items():
        out = tmp_path_factory.mktemp(name)
        cmd = [sys.executable, "-m", "manus_stack.recordings", "--out", str(out), "thesis_circle"]
        subprocess.run(cmd, env=env(), check=True, capture_output=True, timeout=120)
        made[name] = out / "thesis_circle.mcap"
    return made


@pytest.mark.parametrize(("made", "checked"), [("baseline", "native"), ("native", "baseline")])
def test_a_recording_made_under_one_setting_checks_under_the_other(
    recordings: dict[str, Path], made: str, checked: str
) -> None:
    for service in ("planner", "controller"):
        cmd = [sys.executable, "-m", "manus_stack.cli", "replay", str(recordings[made])]
        done = subprocess.run(
            [*cmd, "--check", service],
            env=SETTINGS[checked](),
            capture_output=True,
            text=True,
            timeout=120,
        )
        result = json.loads(done.stdout)
        assert done.returncode == 0 and result["ok"], result
        assert result["compared"] == result["recorded"] > 10
        assert result["tolerance"] == CPU_ROUNDING.relative
        assert result["deviation"] <= MARGIN * CPU_ROUNDING.relative
        print(f"{service}: made {made}, checked {checked}: deviation {result['deviation']:.3g}")


def _with_plan_scaled(path: Path, factor: float) -> Path:
    """tests/data/thesis_square.mcap with the recorded plan's positions times
    ``factor``."""
    with RecordingWriter(path, source="scaled") as writer:
        for r in Recording(SQUARE).messages():
            msg: Message = decode(r)
            if isinstance(msg, PlanReply) and msg.trajectory is not None:
                rows = [[q * factor for q in row] for row in msg.trajectory.positions]
                msg = dataclasses.replace(
                    msg, trajectory=dataclasses.replace(msg.trajectory, positions=rows)
                )
            writer.write(r.suffix, msg, r.log_ns)
    return path


def test_the_planner_tolerance_accepts_rounding_and_catches_a_change(tmp_path: Path) -> None:
    rounded = check_planner(_with_plan_scaled(tmp_path / "rounded.mcap", 1 + 1e-13))
    assert rounded.ok and 0.0 < rounded.deviation < CPU_ROUNDING.relative
    changed = check_planner(_with_plan_scaled(tmp_path / "changed.mcap", 1 + 1e-7))
    assert not changed.ok and changed.difference is not None  # 0.1 µrad per rad
    assert changed.difference.suffix == "trace/planner/plan/reply"
    assert changed.difference.path.startswith("trajectory.positions[")


def test_deviation_and_the_first_difference_beyond_a_tolerance() -> None:
    assert deviation(1.0, 1.0 + 1e-12) == pytest.approx(1e-12, rel=1e-3)
    assert deviation(1e-6, 2e-6) == pytest.approx(1e-6)  # below 1: absolute
    assert deviation(math.nan, math.nan) == deviation(math.inf, math.inf) == 0.0
    assert deviation(1.0, math.inf) == deviation(1.0, math.nan) == math.inf
    near = {"q": [0.5, 1.0 + 1e-12], "n": 3, "name": "a"}
    far = {"q": [0.5, 1.0 + 1e-6], "n": 3, "name": "a"}
    assert first_difference(near, {"q": [0.5, 1.0], "n": 3, "name": "a"}, "", CPU_ROUNDING) is None
    assert first_difference(near, {"q": [0.5, 1.0], "n": 3, "name": "a"}, "", EXACT) == (
        "q[1]",
        1.0 + 1e-12,
        1.0,
    )
    assert first_difference(far, {"q": [0.5, 1.0], "n": 3, "name": "a"}, "", CPU_ROUNDING)
    # integers, strings, types and lengths are never within a tolerance
    assert first_difference({"n": 3}, {"n": 4}, "", CPU_ROUNDING) == ("n", 3, 4)
    assert first_difference([1.0], [1], "", CPU_ROUNDING) == ("[0]", 1.0, 1)
    assert first_difference([1.0], [1.0, 2.0], "", CPU_ROUNDING) == (" (length)", 1, 2)
