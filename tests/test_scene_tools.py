"""``manus scene show|check`` and the clearance panel of ``manus plot``."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from manus.config import DEFAULT_ARM, FOLDED_Q_DEG
from manus.scene import default_scene
from manus_stack.cli import main
from manus_stack.recordings import record_thesis_run
from manus_stack.scene_view import draw_scene
from manus_stack.task_lockstep import TaskLockStep
from schemas import endpoints as ep
from schemas.sequencing import StepKind, Task, TaskState, TaskStep
from services.recorder.plot import load_plot_data, plot_recording
from services.recorder.writer import RecordingWriter


def test_scene_show_draws_the_arm_and_names_the_tightest_clearance(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    png = tmp_path / "scene.png"
    assert (
        main(["scene", "show", "--joints", "0", "-90", "-90", "0", "-90", "0", "-o", str(png)]) == 0
    )
    out = capsys.readouterr().out.splitlines()
    assert out[0] == (
        "q = (0, -90, -90, 0, -90, 0) deg: gripper_motor 20.2 mm from shoulder (self: needs 10 mm)"
    )
    assert out[1] == f"plot: {png}"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_picture_has_a_legend_and_names_file_format_and_scene_version(
    tmp_path: Path,
) -> None:
    q = np.radians(FOLDED_Q_DEG)
    picture = draw_scene(default_scene(), q, tmp_path / "scene.png", arm=DEFAULT_ARM)
    # The file says `version: 1` (its format); the scene version counts run-time updates.
    assert picture.heading == "wheelchair.yaml (file format 1), scene version 0"
    assert picture.legend == [
        "person (needs 50 mm)",
        "chair (needs 15 mm)",
        "environment (needs 15 mm)",
        "keep-out zone",
        "keep-in workspace",
        "arm (self: needs 10 mm)",
        "gripper_motor: tightest clearance",
    ]


def test_scene_check_names_the_file_format_and_the_scene_version(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert main(["scene", "check"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert (out["file_format"], out["scene_version"]) == (1, 0)
    assert "version" not in out


def test_scene_check_refuses_a_malformed_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("version: 1\nmount: {xyz_mm: [0, 0, 0]}\nobjects:\n  - {name: x}\n")
    assert main(["scene", "check", "--scene", str(bad)]) == 1
    err = capsys.readouterr().err
    assert err == f"manus scene: error: {bad}:4: objects[0].class: missing field\n"


def test_plot_shows_the_true_clearance_of_a_run(tmp_path: Path) -> None:
    run = record_thesis_run("square", tmp_path / "square.mcap")
    c = load_plot_data(run.output, DEFAULT_ARM).clearances
    assert len(c.nearest) > 100 and c.contacts == 0
    assert 0.05 < float(c.nearest.min()) < 0.2  # the upper arm passes the thighs
    summary = plot_recording(run.output, tmp_path / "square.png", arm=DEFAULT_ARM)
    assert Path(summary.output).read_bytes()[:4] == b"\x89PNG"
    assert summary.clearance is not None and summary.clearance.check.cls == "person"


def fold_run(path: Path) -> Path:
    """A lock-step fold out and fold in from the folded pose, recorded with the
    simulator's truth at every joint state."""
    rig = TaskLockStep()
    rig.ls.subscribe(ep.JOINTS, lambda m, t: [(ep.SIM_TRUTH, rig.ls.sim.truth(t))])
    rig.start_arm()
    task = Task(steps=[TaskStep(kind=StepKind.FOLD_OUT), TaskStep(kind=StepKind.FOLD_IN)])
    assert rig.submit(task).accepted  # the sequencer checked both folds against the scene
    rig.run_while_busy(120.0)
    assert rig.seq.state == TaskState.SUCCEEDED, rig.seq.reason
    with RecordingWriter(path, source="fold run") as writer:
        for t_ns, suffix, msg in rig.ls.messages:
            writer.write(suffix, msg, t_ns)
    return path


def test_the_folds_keep_every_clearance_and_the_plot_names_the_tightest_pair(
    tmp_path: Path,
) -> None:
    # The arm's own folds, judged on the simulator's truth by the scene's rules: the
    # tightest is the gripper motor passing the shoulder (fold out and fold in), above
    # the arm's self clearance (10 mm) though below the chair's 15 mm, so the plot must
    # name the pair and the rule, not a bare distance.
    recording = fold_run(tmp_path / "folds.mcap")
    c = load_plot_data(recording, DEFAULT_ARM).clearances
    assert [name for _, _, name in c.folds] == ["fold out", "fold in"]
    worst = c.tightest
    assert worst is not None and c.broken == 0 and c.contacts == 0
    assert (worst.check.body, worst.check.other, worst.check.cls) == (
        "gripper_motor", "shoulder", "self",
    )  # fmt: skip
    assert worst.check.required == pytest.approx(0.010)
    assert worst.check.required < worst.distance < 0.015
    assert any(start <= worst.time <= end for start, end, _ in c.folds)  # during a fold
    assert float(c.nearest.min()) == pytest.approx(worst.distance, abs=1e-3)
    summary = plot_recording(recording, tmp_path / "folds.png", arm=DEFAULT_ARM)
    assert summary.clearance_verdict.startswith(
        f"tightest gripper_motor {worst.distance * 1e3:.1f} mm from shoulder (self: needs 10 mm)"
    )
    assert summary.clearance_verdict.endswith("every clearance kept")
