"""``manus demo square`` end to end: every service its own process, over Zenoh, real time.

About 40 s of wall time (the folds and the 19.2 s square run in real time); run in CI.
"""

from __future__ import annotations

import os
import re
import sys
from pathlib import Path

import pytest
from mcap.reader import make_reader

from manus_stack.demo import THESIS_MAX_MM, THESIS_MEAN_MM
from manus_stack.ports import free_port
from manus_stack.regression import check_controller, check_planner
from tests.stack_command import run_stack_command

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.slow(long=True)
@pytest.mark.timeout(240)
def test_demo_square_through_the_real_processes(tmp_path: Path) -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    cmd = [
        sys.executable,
        "-m",
        "manus_stack.cli",
        "demo",
        "square",
        "--plain",
        "--endpoint",
        endpoint,
        "--prefix",
        "demotest",
        "--run-dir",
        str(tmp_path),
    ]
    proc = run_stack_command(cmd, 220, ROOT, dict(os.environ))
    out = proc.stdout
    assert proc.returncode == 0, out + proc.stderr
    assert "step 5/5 fold_in: step_finished" in out
    assert re.search(r"demo: task \w+ succeeded", out)

    # the error table: 17 via points, within the thesis's figures
    rows = re.findall(
        r"^\s+(\d+)\s+(\d*)\s+(\d+\.\d+)(?:\s+\(the start pose: not counted\))?$",
        out,
        flags=re.MULTILINE,
    )
    assert len(rows) == 17 and "(the start pose: not counted)" in out
    mean = float(re.search(r"mean\s+(\d+\.\d+)", out).group(1))  # type: ignore[union-attr]
    worst = float(re.search(r"max\s+(\d+\.\d+)", out).group(1))  # type: ignore[union-attr]
    assert mean < THESIS_MEAN_MM and worst < THESIS_MAX_MM
    # the statistics leave out via point 0 (the start pose)
    assert worst == pytest.approx(max(float(r[2]) for r in rows[1:]), abs=0.01)
    assert mean == pytest.approx(sum(float(r[2]) for r in rows[1:]) / 16, abs=0.01)

    recording = Path(re.search(r"^recording: (.+)$", out, re.MULTILINE).group(1))  # type: ignore[union-attr]
    plot = Path(re.search(r"^plot: (.+)$", out, re.MULTILINE).group(1))  # type: ignore[union-attr]
    with recording.open("rb") as f:
        reader = make_reader(f)
        topics = {channel.topic for _, channel, _ in reader.iter_messages()}
    assert {
        "demotest/state/joints",
        "demotest/controller/result",
        "demotest/sequencer/events",
    } <= topics
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and plot.stat().st_size > 20_000
    # the recorder's plot reads the recording back and finds the same errors
    overview = re.search(
        r"^overview: (\S+) \(from the recording: 1 path\(s\), mean (\d+\.\d+)", out, re.MULTILINE
    )
    assert overview is not None and Path(overview.group(1)).exists()
    assert float(overview.group(2)) == pytest.approx(mean, abs=0.01)
    # and judges the run's clearances on the simulator's truth, naming the pair and its rule
    assert re.search(
        r"^clearances \(simulator's truth\): tightest \w+ \d+\.\d mm from \w+ "
        r"\((person|chair|environment|self|zone): needs \d+ mm\) at t = \d+\.\d s: "
        r"every clearance kept$",
        out,
        re.MULTILINE,
    ), out

    # The recorder started first: the live controller and planner are reproduced, byte
    # for byte, by fresh cores fed the recorded inputs (manus replay --check).
    for service, check in (("controller", check_controller), ("planner", check_planner)):
        result = check(recording)
        assert result.ok, f"{service}: {result.difference}"
        assert result.compared > (900 if service == "controller" else 1)
