"""The joystick option of ``manus jog``: the mapping file, and a recorded input session
(tests/data/joystick_session.jsonl, in the format ``RecordedEvents`` reads) through the
mapping into the lock-step arm, judged on the simulator's truth."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from manus.errors import ConfigError
from manus_stack.jog_lockstep import JogArm, line_drift
from manus_stack.joystick import DEFAULT_MAP, Joystick, JoystickMap, RecordedEvents
from schemas import endpoints as ep
from schemas.jog import JogCommand, JogLevel
from services.controller.jog import JogSource

SESSION = Path(__file__).resolve().parent / "data" / "joystick_session.jsonl"


@pytest.mark.parametrize(
    ("data", "message"),
    [
        ({"axes": {"ABS_X": {"to": "sideways"}}}, "axes.ABS_X.to 'sideways' is not one of"),
        ({"axes": {"ABS_X": {"to": "x", "scale": 40}}}, "axes.ABS_X.scale 40 must be in"),
        ({"buttons": {"BTN_A": "dance"}}, "buttons.BTN_A 'dance' is not one of"),
        ({"deadzone": 1.5}, "deadzone 1.5 must be in"),
        ({"axis": {}}, "unknown key"),
    ],
)
def test_bad_mappings_name_the_key_value_and_what_is_allowed(
    data: dict[str, object], message: str, tmp_path: Path
) -> None:
    path = tmp_path / "map.json"
    path.write_text(json.dumps(data))
    with pytest.raises(ConfigError, match=message) as err:
        JoystickMap.from_file(path)
    assert str(path) in str(err.value)


def test_axes_scale_to_deflections_with_a_dead_zone_and_an_enable_button() -> None:
    mapping = JoystickMap.from_dict(DEFAULT_MAP | {"enable": "BTN_TL2"})
    js = Joystick(mapping=mapping, ranges={"ABS_Y": (-32768, 32767), "ABS_X": (0, 255)})
    js.event("EV_ABS", "ABS_Y", -32768, 0.0)
    js.event("EV_ABS", "ABS_X", 140, 0.0)  # 0.1 off centre: inside the dead zone
    assert js.command(0.0)["kind"] == "stop"  # not enabled
    js.event("EV_KEY", "BTN_TL2", 1, 0.0)
    cmd = js.command(0.0)
    assert cmd["linear"] == pytest.approx([1.0, 0.0, 0.0])
    js.event("EV_ABS", "ABS_X", 0, 0.0)
    assert js.command(0.0)["linear"] == pytest.approx([1.0, 1.0, 0.0])  # left: +y
    js.event("EV_KEY", "BTN_TL2", 0, 0.0)
    assert js.command(0.0)["kind"] == "stop"


def test_buttons_step_levels_switch_modes_and_drink_mode_pours_with_the_pad() -> None:
    js = Joystick()
    assert js.event("EV_KEY", "BTN_TR", 1, 0.0) == 4
    assert js.event("EV_KEY", "BTN_TR", 2, 0.0) is None  # auto-repeat: ignored
    assert js.event("EV_KEY", "BTN_TL", 1, 0.0) == 3
    js.event("EV_KEY", "BTN_WEST", 1, 0.0)  # drink mode
    js.event("EV_ABS", "ABS_HAT0Y", -1, 0.0)  # pad up: pitch, held in drink mode: pours
    js.ranges["ABS_HAT0Y"] = (-1, 1)
    js.event("EV_ABS", "ABS_HAT0Y", -1, 0.0)
    cmd = js.command(0.0)
    assert cmd["drink"] and cmd["pour"] == pytest.approx(1.0) and cmd["angular"][1] == 0.0
    JogCommand(stamp_ns=0, seq=1, source="t", **cmd)
    js.event("EV_KEY", "BTN_SOUTH", 1, 0.0)
    assert js.command(0.0)["kind"] == "twist"  # stop clears keys; the pad is still held
    js.event("EV_ABS", "ABS_HAT0Y", 0, 0.0)
    assert js.command(0.0)["kind"] == "stop"


def test_a_recorded_session_drives_the_arm_straight_along_x() -> None:
    events = RecordedEvents(SESSION)
    assert events.ranges["ABS_Y"] == (-32768, 32767)
    js = Joystick(ranges=events.ranges)
    arm = JogArm()
    arm.start()
    arm.run(0.3)
    t0 = arm.ls.t_ns
    first = len(arm.samples)
    while not events.done or arm.ls.t_ns - t0 < 2.5e9:  # 20 Hz, as manus jog sends
        now = (arm.ls.t_ns - t0) / 1e9
        for kind, code, value in events.due(now):
            level = js.event(kind, code, value, now)
            if level is not None:
                assert arm.query(ep.JOG_LEVEL, JogLevel(level=level)).accepted
        arm.send(**js.command(now))
        arm.run(0.05)
    assert arm.core.source(JogSource).level == 4
    drift, along, turned = line_drift(arm.samples[first:], np.array([1.0, 0.0, 0.0]))
    # 1 s at full deflection of level 4 (120 mm/s) after 0.1 s at half
    assert 0.09 < along < 0.15, along
    assert drift < 0.001 and turned < 0.5
    assert arm.samples[-1].at_rest and not arm.core.source(JogSource).engaged
