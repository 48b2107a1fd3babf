"""Exports (JSON MCAP for Foxglove, candump), the plot, and replay-based regression checks
on the lock-step recordings of the thesis paths kept in tests/data."""

from __future__ import annotations

import base64
import dataclasses
import json
from collections.abc import Callable
from pathlib import Path

import can
import jsonschema
import msgpack
import numpy as np
import pytest
from PIL import Image

from manus_stack.cli import main
from manus_stack.comparison import first_difference
from manus_stack.controlled import controller_input
from manus_stack.recordings import record_thesis_run
from manus_stack.regression import check_controller, check_planner
from manus_stack.service_window import EVERYTHING, service_window
from schemas.base import Message
from schemas.collision import SceneState
from schemas.commands import JointVelocityCommand
from schemas.liveliness import LIVELINESS, LivelinessChange
from schemas.state import CanFrame
from services.controller.config import ControllerConfig
from services.controller.core import ControllerCore
from services.controller.wiring import WIRING as CONTROLLER
from services.recorder.errors import RecordingError
from services.recorder.export import export_candump
from services.recorder.reading import Recording, decode
from services.recorder.replay import schedule
from services.recorder.writer import RecordingWriter
from tests.controller_plant import steps

DATA = Path(__file__).resolve().parent / "data"
SQUARE = DATA / "thesis_square.mcap"
CIRCLE = DATA / "thesis_circle.mcap"
SQUARE_THESIS = DATA / "thesis_square_thesis_mode.mcap"
REGENERATE = "python -m manus_stack.recordings, then look at manus plot tests/data/*.mcap"


def test_json_export_keeps_everything_and_validates_against_the_schemas(tmp_path: Path) -> None:
    out = tmp_path / "square.json.mcap"  # the recorded channels only (tests/test_viewer.py: more)
    assert main(["export", str(SQUARE), "--json", "--no-view", "-o", str(out)]) == 0
    src, dst = Recording(SQUARE), Recording(out)
    assert dst.info.messages == src.info.messages
    validators = {}
    for key, channel in dst.info.channels.items():
        assert channel.message_encoding == "json"
        assert channel.schema == src.info.channels[key].schema
        validators[key] = jsonschema.Draft202012Validator(channel.schema)
    for a, b in zip(src.messages(), dst.messages(), strict=True):
        assert (a.key, a.log_ns, a.publish_ns, a.sequence) == (
            b.key,
            b.log_ns,
            b.publish_ns,
            b.sequence,
        )
        value = json.loads(b.payload)
        validators[b.key].validate(value)
        original = msgpack.unpackb(a.payload, raw=False)
        if isinstance(original.get("data"), bytes):  # CAN payloads travel as base64
            assert base64.b64decode(value["data"]) == original["data"]
        else:
            assert value == original


def test_candump_export_round_trips_through_python_can(tmp_path: Path) -> None:
    out = tmp_path / "square.log"
    assert main(["export", str(SQUARE), "--candump", "-o", str(out)]) == 0
    frames = [(r.suffix, decode(r)) for r in Recording(SQUARE).messages(["can/rx", "can/tx"])]
    read = list(can.LogReader(str(out)))
    assert len(read) == len(frames) > 1000
    for (suffix, frame), msg in zip(frames, read, strict=True):
        assert isinstance(frame, CanFrame)
        assert msg.arbitration_id == frame.id and msg.is_remote_frame == frame.remote
        assert msg.is_rx == (suffix == "can/rx")
        if not frame.remote:
            assert bytes(msg.data) == frame.data
        assert msg.timestamp == pytest.approx(frame.stamp_ns / 1e9, abs=1e-6)
    assert {m.arbitration_id for m in read} >= {0x350, 0x360, 0x37F, 0x374}


def test_export_info_describes_the_recording(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["export", str(SQUARE), "--info"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["prefix"] == "manus" and info["source"].startswith("lockstep thesis_square")
    assert info["channels"]["state/joints"]["type"] == "manus/JointState/2"
    assert info["messages"] == sum(c["messages"] for c in info["channels"].values())
    assert 20.0 < info["duration_s"] < 30.0


def test_candump_export_needs_can_channels(tmp_path: Path) -> None:
    empty = tmp_path / "nocan.mcap"
    RecordingWriter(empty).close()
    with pytest.raises(RecordingError, match="no can/rx or can/tx"):
        export_candump(empty, tmp_path / "x.log")
    assert main(["export", str(empty), "--candump"]) == 1


def test_plot_writes_a_non_blank_png(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    png = tmp_path / "square.png"
    assert main(["plot", str(SQUARE), "-o", str(png)]) == 0
    summary = json.loads(capsys.readouterr().out)
    # 17 via points, the start pose not scored
    assert summary["goals"] == 1 and summary["via_points"] == 16
    assert 0.0 < summary["mean_mm"] <= summary["max_mm"] < 10.0
    with Image.open(png) as image:
        assert image.size[0] >= 800 and image.size[1] >= 600
        pixels = np.asarray(image.convert("RGB"), dtype=float)
    colours = len(np.unique(pixels.reshape(-1, 3), axis=0))
    assert colours > 50  # lines of several colours, text, a table
    assert (pixels.min(axis=2) < 128).mean() > 0.01  # not a blank page


def test_plot_of_a_recording_without_arm_data_is_refused(tmp_path: Path) -> None:
    empty = tmp_path / "empty.mcap"
    RecordingWriter(empty).close()
    assert main(["plot", str(empty)]) == 1


@pytest.mark.parametrize(
    "path", [SQUARE, CIRCLE, SQUARE_THESIS], ids=["square", "circle", "thesis"]
)
def test_controller_core_reproduces_the_recorded_run(path: Path) -> None:
    result = check_controller(path)
    assert result.ok, f"{result.difference} (if the controller changed on purpose: {REGENERATE})"
    assert result.compared == result.recorded == result.replayed
    commands = Recording(path).info.channels["manus/cmd/joint_velocity"].messages
    assert result.compared > commands > 300


@pytest.mark.parametrize("path", [SQUARE, CIRCLE], ids=["square", "circle"])
def test_planner_core_reproduces_the_recorded_plan(path: Path) -> None:
    result = check_planner(path)
    assert result.ok, str(result.difference)
    # the plan, and the scene in use and the world model once a second of the recording
    # (at the first joint state, then every 1000 ms of stamps: 17 cycles of 60 ms)
    states = len(list(Recording(path).messages(["planner/scene_state"])))
    objects = len(list(Recording(path).messages(["planner/objects"])))
    assert states >= 15 and objects == states
    # the scene's repeats are compared as the scene's changes: one scene here
    assert result.compared == 1 + 1 + objects


def test_the_scene_is_checked_by_its_changes_not_by_which_joint_state_repeated_it(
    tmp_path: Path,
) -> None:
    """A live planner that did not take a joint state the recorder did (a loaded
    computer) repeats its scene at other joint states after it: not a difference. A
    scene of another content is."""
    src = Recording(SQUARE)

    def rewritten(name: str, change: Callable[[int, SceneState], SceneState | None]) -> Path:
        out = tmp_path / name
        with RecordingWriter(out, source=name) as writer:
            rank = 0
            for r in src.messages():
                msg: Message | None = decode(r)
                if r.suffix == "planner/scene_state":
                    assert isinstance(msg, SceneState)
                    msg = change(rank, msg)
                    rank += 1
                if msg is not None:
                    writer.write(r.suffix, msg, r.log_ns)
        return out

    skipped = rewritten("skipped.mcap", lambda rank, m: None if rank in (3, 7) else m)
    assert check_planner(skipped).ok
    changed = rewritten(
        "changed.mcap",
        lambda rank, m: dataclasses.replace(m, text=m.text + "# edited\n") if rank == 5 else m,
    )
    result = check_planner(changed)
    assert not result.ok and result.difference is not None
    assert result.difference.suffix == "planner/scene_state"


def test_replay_as_bridge_drives_a_controller_core_to_the_same_commands() -> None:
    rec = Recording(SQUARE)
    bridge = schedule(rec, as_service="can_bridge")
    assert {s.rec.suffix for s in bridge} == {
        "state/joints",
        "state/status",
        "state/bridge",
        "can/rx",
        "can/tx",
    }
    goals = list(rec.messages(["trace/controller/goal/request"]))
    inputs = sorted([s.rec for s in bridge] + goals, key=lambda r: r.log_ns)
    core = ControllerCore()
    commands = [
        out.encode()
        for r in inputs
        for suffix, out in controller_input(core, r.suffix, decode(r))
        if suffix == "cmd/joint_velocity"
    ]
    recorded = [r.payload for r in rec.messages(["cmd/joint_velocity"])]
    assert commands == recorded
    moving = [c for c in map(JointVelocityCommand.decode, commands) if any(steps(c))]
    assert len(moving) > 100


def test_a_changed_controller_is_caught_with_the_first_difference() -> None:
    result = check_controller(SQUARE, ControllerConfig(default_quantizer="rounding"))
    assert not result.ok and result.difference is not None
    diff = result.difference
    assert diff.suffix in ("cmd/joint_velocity", "controller/feedback")
    assert diff.path and diff.recorded != diff.replayed
    assert diff.suffix in str(diff) and "recorded" in str(diff)


def test_a_tampered_recording_is_caught_at_the_tampered_message(tmp_path: Path) -> None:
    src = Recording(SQUARE)
    target = 200  # the 201st command
    out = tmp_path / "tampered.mcap"
    with RecordingWriter(out, source="tampered") as writer:
        rank = 0
        for r in src.messages():
            msg: Message = decode(r)
            if r.suffix == "cmd/joint_velocity":
                if rank == target:
                    assert isinstance(msg, JointVelocityCommand)
                    msg = dataclasses.replace(msg, velocity=[*msg.velocity[:5], 1.0])
                rank += 1
            writer.write(r.suffix, msg, r.log_ns)
    result = check_controller(out)
    assert result.difference is not None
    assert (result.difference.suffix, result.difference.rank) == ("cmd/joint_velocity", target)
    assert result.difference.path == "velocity[5]" and result.difference.recorded == 1.0
    assert main(["replay", str(out), "--check", "controller"]) == 1


def _live_like(
    out: Path, *, appear_s: float, vanish_s: float | None, drop_outputs_after_s: float
) -> Path:
    """The square's recording as a live one would look: the controller's ``where`` token
    appears at ``appear_s`` and vanishes at ``vanish_s`` (recording times), it published
    nothing after ``drop_outputs_after_s``, and the bridge went on publishing."""
    src = Recording(SQUARE)
    start = min(r.log_ns for r in src.messages())
    key = "manus/where/controller/host/4711"
    outputs = ("cmd/joint_velocity", "controller/feedback", "controller/result")
    changes = [(appear_s, True)] + ([] if vanish_s is None else [(vanish_s, False)])
    with RecordingWriter(out, source="live-like") as writer:
        for r in src.messages():
            while changes and r.log_ns >= start + changes[0][0] * 1e9:
                at, alive = changes.pop(0)
                t = start + round(at * 1e9)
                change = LivelinessChange.from_token(
                    key, key.removeprefix("manus/"), alive=alive, stamp_ns=t, seq=0
                )
                writer.write(LIVELINESS, change, t)
            if r.suffix in outputs and r.log_ns > start + drop_outputs_after_s * 1e9:
                continue
            writer.write(r.suffix, decode(r), r.log_ns)
    return out


def test_a_live_check_stops_at_the_last_output_of_the_controllers_process(
    tmp_path: Path,
) -> None:
    # It stopped at 12 s (its token vanished a moment later); the bridge went on.
    stopped = _live_like(tmp_path / "a.mcap", appear_s=0.0, vanish_s=12.01, drop_outputs_after_s=12)
    result = check_controller(stopped)
    assert result.ok, result.difference
    assert 0 < result.compared < check_controller(SQUARE).compared
    # The recorder stopped before it: nothing recorded after 12 s, the token still up.
    cut = _live_like(tmp_path / "b.mcap", appear_s=0.0, vanish_s=None, drop_outputs_after_s=12)
    assert check_controller(cut).ok
    # Alive but silent: a difference, not an empty check.
    silent = _live_like(tmp_path / "c.mcap", appear_s=0.0, vanish_s=None, drop_outputs_after_s=-1)
    result = check_controller(silent)
    assert not result.ok and result.difference is not None
    assert result.difference.recorded is None  # the replay answered, the recording did not


def test_a_live_check_feeds_only_what_came_while_the_first_process_listened(
    tmp_path: Path,
) -> None:
    late = _live_like(tmp_path / "late.mcap", appear_s=0.5, vanish_s=15.0, drop_outputs_after_s=14)
    rec = Recording(late)
    first = min(r.log_ns for r in rec.messages())
    start, end = service_window(rec, "controller")
    assert (start - first, end - first) == (500_000_000, 15_000_000_000)
    last_out = max(r.log_ns for r in rec.messages(["cmd/joint_velocity"]))
    fed = [r for r in rec.messages(CONTROLLER.input_suffixes) if start <= r.log_ns <= last_out]
    assert 0 < len(fed) < sum(1 for _ in rec.messages(CONTROLLER.input_suffixes))
    assert check_controller(late).inputs == len(fed)
    # Lock-step recordings have no liveliness channel: everything is fed.
    assert service_window(Recording(SQUARE), "controller") == EVERYTHING


def test_outputs_recorded_before_the_token_start_the_window_at_the_state_they_answer(
    tmp_path: Path,
) -> None:
    """A service announces its token once it listens, and the recorder hears liveliness on
    another path than data: its first command can be recorded before its token."""
    src = Recording(SQUARE)
    start = min(r.log_ns for r in src.messages())
    first_cmd = min(r.log_ns for r in src.messages(["cmd/joint_velocity"]))
    answered = max(r.log_ns for r in src.messages(["state/joints"]) if r.log_ns <= first_cmd)
    early = _live_like(
        tmp_path / "early.mcap",
        appear_s=(first_cmd - start) / 1e9 + 0.0005,
        vanish_s=None,
        drop_outputs_after_s=1e9,
    )
    assert service_window(Recording(early), "controller")[0] > first_cmd  # the token alone
    window = service_window(
        Recording(early), "controller", ("state/joints",), CONTROLLER.output_suffixes
    )
    assert window[0] == answered
    result = check_controller(early)
    assert result.ok, result.difference
    assert result.compared == check_controller(SQUARE).compared


def test_the_window_follows_the_first_process_not_a_restart(tmp_path: Path) -> None:
    out = tmp_path / "restart.mcap"
    with RecordingWriter(out, source="restart") as writer:
        for t, pid, alive in ((1, 10, True), (2, 11, True), (3, 10, False), (4, 11, False)):
            key = f"manus/where/controller/h/{pid}"
            change = LivelinessChange.from_token(
                key, key.removeprefix("manus/"), alive=alive, stamp_ns=t, seq=0
            )
            writer.write(LIVELINESS, change, t * 1_000_000_000)
    assert service_window(Recording(out), "controller") == (1_000_000_000, 3_000_000_000)
    assert service_window(Recording(out), "planner") == EVERYTHING


def test_first_difference_names_the_field() -> None:
    assert first_difference({"a": [1, 2, {"b": 3}]}, {"a": [1, 2, {"b": 4}]}) == ("a[2].b", 3, 4)
    assert first_difference({"a": [1]}, {"a": [1, 2]}) == ("a (length)", 1, 2)
    assert first_difference({"a": 1}, {"a": 1.0}) == ("a", 1, 1.0)
    assert first_difference({"a": 1}, {"a": 1}) is None


def test_a_fresh_lockstep_recording_passes_its_own_checks(tmp_path: Path) -> None:
    """The generator of tests/data and the checks agree on a run made now (whatever the
    cores do today), so a failure of the tests above means the cores changed."""
    run = record_thesis_run("square", tmp_path / "square.mcap")
    assert run.status == "succeeded" and len(run.via_errors_mm) == 17
    assert check_controller(run.output).ok
    assert check_planner(run.output).ok
