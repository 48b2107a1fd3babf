"""``manus demo drink`` end to end: every service its own process, over Zenoh, real time,
judged on the simulator's truth (docs/drink.md).

About 90 s of wall time (the whole drink in real time, 5 s at the mouth): skipped unless
``MANUS_TEST_LIVE_DRINK=1`` (marker ``live_drink``, docs/testing.md).
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import pytest
from mcap.reader import make_reader

from manus_stack.drink import MAX_TILT_DEG, PLACE_TOLERANCE_M
from manus_stack.ports import free_port
from tests.stack_command import run_stack_command

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.slow
@pytest.mark.live_drink
@pytest.mark.timeout(420)
def test_demo_drink_through_the_real_processes(tmp_path: Path) -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    cmd = [sys.executable, "-m", "manus_stack.cli", "demo", "drink", "--seed", "0",
           "--plain", "--endpoint", endpoint, "--prefix", "drinktest",
           "--run-dir", str(tmp_path)]  # fmt: skip
    proc = run_stack_command(cmd, 400, ROOT, dict(os.environ))
    out = proc.stdout
    assert proc.returncode == 0, out + proc.stderr
    assert "step 4/7 follow: step_finished" in out and "the user says done" in out
    figures = json.loads(out.strip().splitlines()[-1])
    assert figures["ok"], figures["failure"]
    assert list(figures["phases_s"]) == [
        "1 fold_out", "2 pick", "3 give", "4 follow", "5 place", "6 reach", "7 fold_in"
    ]  # fmt: skip
    assert figures["contacts"] == 0 and figures["person_contacts"] == 0
    clearance = figures["person_clearance_mm"]
    assert figures["arm_min_person_mm"] > clearance
    assert figures["cup_min_person_mm"] > clearance
    assert figures["tilt_max_deg"] <= MAX_TILT_DEG
    assert figures["placement_error_mm"] <= PLACE_TOLERANCE_M * 1e3

    recording = tmp_path / "recording.mcap"
    with recording.open("rb") as f:
        topics = {channel.topic for _, channel, _ in make_reader(f).iter_messages()}
    assert {"drinktest/sim/truth", "drinktest/controller/follow_state"} <= topics
    plot = tmp_path / "demo_drink.png"
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
