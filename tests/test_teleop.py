"""``manus jog``: the key mapping alone, the refusal without a terminal, and the real
program in a tmux terminal against the real controller shell on a loopback router."""

from __future__ import annotations

import math
import os
import shutil
import subprocess
import sys
import uuid
from pathlib import Path

import pytest

from manus.session import ZenohSettings
from manus_stack.teleop import Teleop, screen
from schemas.jog import JogCaps, JogCommand, JogState
from services.controller.jog import JogSource
from services.controller.shell import ControllerShell
from tests.conftest import eventually

ROOT = Path(__file__).resolve().parents[1]
MANUS = Path(sys.executable).with_name("manus")


def _state(**kw: object) -> JogState:
    base: dict[str, object] = {
        "stamp_ns": 0, "seq": 0, "state": "running", "active": True, "cause": "",
        "kind": "twist", "frame": "base", "drink": False, "level": 3, "levels": 5,
        "caps": JogCaps(linear=0.09, angular=0.3, joints=0.5, gripper=0.018), "scale": 1.0,
        "limits": [], "reason": "", "command_seq": 1, "refused": 0, "deadman_stops": 0,
        "folded": False, "actual_xyz": [0.2, 0.1, 0.3], "actual_ypr": [0.0, -math.pi / 3, 0.0],
    }  # fmt: skip
    return JogState(**(base | kw))  # type: ignore[arg-type]


def test_keys_hold_their_axis_for_the_hold_time_and_space_stops() -> None:
    t = Teleop(hold_s=0.5)
    assert t.command(0.0) == {"kind": "stop", "units": "unitless"}
    t.key("w", 0.0)
    t.key("f", 0.1)
    cmd = t.command(0.2)
    assert cmd["kind"] == "twist" and cmd["linear"] == [1.0, 0.0, -1.0]
    cmd_fields = JogCommand(stamp_ns=0, seq=1, source="t", **cmd)  # the fields are valid
    assert cmd_fields.frame == "base"
    assert t.command(0.55)["linear"] == [0.0, 0.0, -1.0]  # w expired, f still held
    t.key(" ", 0.56)
    assert t.command(0.57)["kind"] == "stop"


def test_frames_modes_levels_and_quit() -> None:
    t = Teleop(deflection=0.5)
    t.key("b", 0.0)
    t.key("j", 0.0)
    cmd = t.command(0.1)
    assert cmd["frame"] == "gripper" and cmd["angular"] == [0.0, 0.0, 0.5]
    t.key("t", 0.2)
    t.key("u", 0.2)
    t.key("]", 0.2)
    cmd = t.command(0.3)
    assert cmd["kind"] == "joints" and cmd["joints"] == [0.0, 0.0, 0.0, 0.5, 0.0, 0.0]
    assert cmd["gripper"] == 0.5
    assert t.key("4", 0.4) == 4 and t.key("9", 0.4) is None
    t.key("q", 0.5)
    assert t.quit and t.command(0.5)["kind"] == "stop"


def test_drink_mode_holds_pitch_and_roll_and_i_k_pour() -> None:
    t = Teleop()
    t.key("c", 0.0)
    t.key("i", 0.0)
    t.key("u", 0.0)  # roll: held, not sent
    t.key("l", 0.0)
    cmd = t.command(0.1)
    assert cmd["drink"] and cmd["pour"] == 1.0
    assert cmd["angular"] == [0.0, 0.0, -1.0]
    assert "holds the roll" in t.status
    JogCommand(stamp_ns=0, seq=1, source="t", **cmd)


def test_screen_shows_pose_level_mode_reasons_and_warnings() -> None:
    t = Teleop()
    t.key("w", 0.0)
    lines = screen(t, 0.1, _state(reason="slowed to 40 %: wrist singularity"), None, None)
    text = "\n".join(lines)
    assert "level: 3/5" in text and "moving: x+" in text and "Cartesian, base frame" in text
    assert "200.0   100.0   300.0" in text and "-60.0" in text
    assert "slowed to 40 %: wrist singularity" in text
    assert "no JogState yet" in "\n".join(screen(t, 0.1, None, None, None))


def test_not_a_terminal_is_refused_with_a_reason() -> None:
    proc = subprocess.run(
        [str(MANUS), "jog", "--connect", "tcp/127.0.0.1:9"],
        stdin=subprocess.DEVNULL,
        capture_output=True,
        text=True,
        timeout=30,
    )
    assert proc.returncode == 2
    assert "must be a terminal" in proc.stderr


TMUX = ["tmux", "-L", f"manus-test-{os.getpid()}"]
"""tmux on a server of this test process's own: the default server is shared with every
other tmux user of the machine, whose clients can resize its windows."""


def _tmux(*args: str) -> str:
    return subprocess.run([*TMUX, *args], capture_output=True, text=True, timeout=10,
                          check=True).stdout  # fmt: skip


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("tmux") is None, reason="tmux is not installed")
@pytest.mark.parametrize("ending", ["q", "sigterm"])
def test_manus_jog_in_a_terminal_drives_the_controller_and_restores_the_terminal(
    zenoh_settings: ZenohSettings, router_endpoint: str, tmp_path: Path, ending: str
) -> None:
    session = f"manus-jog-test-{uuid.uuid4().hex[:8]}"
    stty = tmp_path / "stty.txt"
    script = (  # stty -g: the settings alone (-a lays them out to the window's width)
        f"stty -g > {tmp_path / 'before.txt'}; "
        f"{MANUS} jog --connect {router_endpoint} --prefix test; "
        f"stty -a > {stty}; stty -g > {tmp_path / 'after.txt'}; sleep 30"
    )
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    with ControllerShell(zenoh_settings) as controller:
        subprocess.run(
            [*TMUX, "new-session", "-d", "-s", session, "-x", "120", "-y", "30", "bash", "-c",
             script],
            check=True, timeout=10, env=env,
        )  # fmt: skip
        try:
            eventually(lambda: "manus jog" in _tmux("capture-pane", "-p", "-t", session), 20.0,
                       "the teleop's screen")  # fmt: skip
            _tmux("send-keys", "-t", session, "4")
            eventually(lambda: controller.core.source(JogSource).level == 4, 10.0, "level 4 set")
            _tmux("send-keys", "-t", session, "w")
            # no arm: the controller refuses the jog (no joint state) and counts it
            eventually(
                lambda: controller.core.source(JogSource).refused >= 1, 10.0, "the jog refused"
            )
            assert "no valid joint state" in controller.core.source(JogSource).reason
            if ending == "q":
                _tmux("send-keys", "-t", session, "q")
            else:  # the pane's shell runs the teleop as its one child
                shell = int(_tmux("list-panes", "-t", session, "-F", "#{pane_pid}").split()[0])
                found = subprocess.run(
                    ["pgrep", "-P", str(shell)], capture_output=True, text=True, timeout=10
                )
                child = found.stdout.split()
                assert len(child) == 1, child
                os.kill(int(child[0]), 15)
            after = tmp_path / "after.txt"
            eventually(lambda: after.exists() and after.stat().st_size > 0, 20.0, "the exit")
        finally:
            subprocess.run([*TMUX, "kill-session", "-t", session], timeout=10, check=False)
    settings = stty.read_text()
    assert " icanon" in settings and " echo " in settings, settings  # the terminal restored
    assert after.read_text() == (tmp_path / "before.txt").read_text()


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("tmux") is None, reason="tmux is not installed")
def test_manus_jog_plays_a_recorded_joystick_session(
    zenoh_settings: ZenohSettings, router_endpoint: str, tmp_path: Path
) -> None:
    session = f"manus-jog-test-{uuid.uuid4().hex[:8]}"
    done = tmp_path / "done"
    recording = ROOT / "tests" / "data" / "joystick_session.jsonl"
    script = (
        f"{MANUS} jog --connect {router_endpoint} --prefix test --joystick-replay {recording}; "
        f"echo $? > {done}; sleep 30"
    )
    with ControllerShell(zenoh_settings) as controller:
        subprocess.run(
            [*TMUX, "new-session", "-d", "-s", session, "-x", "120", "-y", "30", "bash", "-c",
             script],
            check=True, timeout=10, env=dict(os.environ, PYTHONPATH=str(ROOT)),
        )  # fmt: skip
        try:
            eventually(
                lambda: controller.core.source(JogSource).level == 4, 20.0, "level 4 from BTN_TR"
            )
            # the stick pushed forward: a jog (refused here: no arm, no joint state)
            eventually(
                lambda: controller.core.source(JogSource).refused >= 1, 10.0, "the stick's jog"
            )
            _tmux("send-keys", "-t", session, "q")
            eventually(lambda: done.exists() and done.read_text().strip() == "0", 20.0, "exit 0")
        finally:
            subprocess.run([*TMUX, "kill-session", "-t", session], timeout=10, check=False)
