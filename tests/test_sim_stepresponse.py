"""The step-response experiment (docs/protocol.md, Thesis step response) and its command."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from manus_stack.cli import main
from services.simulator.stepresponse import step_run


@pytest.mark.parametrize("counts", [1, 4, 10])
def test_still_for_60_ms_then_the_commanded_slope(counts: int) -> None:
    run = step_run(counts)
    assert run.encoder_t_ms[:2].tolist() == [0.0, 60.0]
    assert run.encoder_deg[:2].tolist() == [0.0, 0.0]
    still = run.truth_t_ms <= 60.0
    assert np.all(run.truth_deg[still] == 0.0)
    # From 120 ms on the speed holds at the command (5 deg/s per count, +-1.5 % gain).
    late = run.truth_t_ms >= 150.0
    slope = np.polyfit(run.truth_t_ms[late] / 1000.0, run.truth_deg[late], 1)[0]
    assert slope == pytest.approx(5.0 * counts, rel=0.016)
    assert np.all(np.diff(run.encoder_deg) >= 0.0)


def test_manus_sim_step_response_writes_the_png(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "fig51.png"
    assert main(["sim", "--step-response", str(out)]) == 0
    assert capsys.readouterr().out.strip() == f"plot: {out}"
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
