"""The panel's plain language and its model of the page: every trouble has one sentence;
the reports the real cores write (sequencer, planner, controller, bridge, simulator in
lock-step) become the right sentence; the task buttons' file is checked with messages
that name the file, the button and the key."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from manus.errors import ConfigError
from manus_stack.panel.keys import PANEL_KEYS
from manus_stack.panel.tasks import DEFAULT_DIR, TaskButton, load_buttons
from manus_stack.panel.view import PanelView
from manus_stack.panel.words import (
    SENTENCES,
    Trouble,
    jog_trouble,
    refusal_trouble,
    sentence,
    task_trouble,
)
from manus_stack.task_lockstep import TaskLockStep
from schemas import endpoints as ep
from schemas.commands import EStop
from schemas.sequencing import SubmitReply, TaskEvent

# -- the sentences -------------------------------------------------------------------------------


def test_every_trouble_has_one_plain_sentence() -> None:
    assert set(SENTENCES) == set(Trouble)
    for trouble, _text in SENTENCES.items():
        said = sentence(trouble, "the cup")
        assert said[0].isupper() and said.endswith("."), said
        # no key names, phases or enum values: words a person reads
        assert not re.search(r"[a-z]+_[a-z]+|/", said), said
    assert sentence(Trouble.OUT_OF_REACH, "the cup") == "The cup is out of reach."
    assert sentence(Trouble.OUT_OF_REACH) == "That place is out of reach."


@pytest.mark.parametrize(
    ("reason", "trouble"),
    [
        ("step 1 (pose): planner refused (unreachable): via point 2 ...", Trouble.OUT_OF_REACH),
        ("step 2 (move): planner refused (collision): gripper 3 mm from head", Trouble.TOO_CLOSE),
        ("step 1 (move): planner refused (joint_limit): joint 3 ...", Trouble.OUT_OF_REACH),
        ("step 1 (move): planner refused: the path leaves the workspace", Trouble.OUT_OF_REACH),
        ("step 1 (fold_out): e-stop engaged by panel: STOP pressed", Trouble.STOPPED),
        ("step 1 (fold_in): can_bridge: phase arm_error: arm error 3", Trouble.ARM_ERROR),
        (
            "step 1 (fold_out): can_bridge: phase stopped: fold_out stopped: lost the "
            "supervisor's heartbeat (newest echo 212 ms old)",
            Trouble.HELD_STOPPED,
        ),
        (
            "the bridge is not running (stopped: frames from the arm again); a task starts only",
            Trouble.HELD_STOPPED,
        ),
        (
            "step 2 (move): controller: goal aborted: lost the supervisor's heartbeat: ...",
            Trouble.LINK_LOST,
        ),
        ("step 1 (move): planner is gone (its liveliness token vanished)", Trouble.PARTS_MISSING),
        ("step 1 (move): no joint states from the arm for 812 ms ...", Trouble.LINK_LOST),
        ("step 1 (fold_out): the fold did not complete within 30 s", Trouble.TIMED_OUT),
        ("step 1 (move): controller: goal aborted: collision guard: ...", Trouble.TOO_CLOSE),
        ("user took over", Trouble.TOOK_OVER),
        ("cancelled by request", Trouble.CANCELLED),
        ("something nobody wrote a sentence for", Trouble.UNKNOWN),
    ],
)
def test_reports_are_sorted_into_troubles(reason: str, trouble: Trouble) -> None:
    assert task_trouble(reason) is trouble


def test_a_refusal_names_the_trouble_that_explains_the_others() -> None:
    reply = SubmitReply(accepted=False, task_id="", errors=[
        "home.toml:5: step 1 (pose): planner refused (branch): joint 1 would jump",
        "home.toml:5: step 1 (pose): the arm is folded there: unfold it first",
    ])  # fmt: skip
    assert refusal_trouble(reply) is Trouble.FOLDED
    busy = SubmitReply(accepted=False, task_id="", errors=["busy: task t3 is running; cancel it"])
    assert refusal_trouble(busy) is Trouble.BUSY


def test_the_jog_says_why_it_stopped() -> None:
    late = "stopped: deadman: no jog command within jog_timeout 150 ms; release the controls"
    assert jog_trouble(late, refused=False) is Trouble.JOG_LATE
    held = "stopped: jog command seq 7 refused: bridge phase estopped; release the controls"
    assert jog_trouble(held, refused=True) is Trouble.STOPPED
    stopped = (
        "stopped: jog command seq 9 refused: the bridge is in phase 'stopped', not "
        "'running' (clear it or wait for it first); release the controls"
    )
    assert jog_trouble(stopped, refused=True) is Trouble.HELD_STOPPED
    # a stop keeps its words while it holds commands back (JogState, docs/jog.md)
    phase = "stopped: bridge phase stopped: stop requested by t; release the controls"
    assert jog_trouble(phase, refused=True) is Trouble.HELD_STOPPED
    error = "stopped: arm error: motor 2 overload; release the controls"
    assert jog_trouble(error, refused=True) is Trouble.ARM_ERROR
    assert jog_trouble("released", refused=False) is None
    assert jog_trouble("", refused=False) is None


# -- the task buttons ----------------------------------------------------------------------------


def test_the_shipped_buttons_load_every_task_set_up(tmp_path: Path) -> None:
    buttons = {b.id: b for b in load_buttons()}
    assert list(buttons) == ["drink", "fetch", "home", "unfold", "fold"]
    assert all(b.ready for b in buttons.values())
    assert buttons["fetch"].objects == ("cup", "bottle", "phone")
    assert buttons["fetch"].about_words("bottle") == "the bottle"
    assert buttons["fold"].sentence(Trouble.FOLDED) == "The arm is already folded."
    drink = buttons["drink"].task()
    assert [s.kind for s in drink.steps] == [
        "fold_out", "pick", "give", "follow", "place", "reach", "fold_in"
    ]  # fmt: skip
    assert drink.steps[4].back and drink.steps[4].object == "cup"
    fetch = buttons["fetch"].task("bottle")
    assert [(s.kind, s.object) for s in fetch.steps] == [("pick", "bottle"), ("give", "bottle")]
    d = _write(tmp_path, '[[button]]\nid = "x"\nlabel = "X"\ntask = "x.toml"\n')
    (missing,) = load_buttons(d)
    assert not missing.ready
    with pytest.raises(ConfigError, match="does not exist"):
        missing.task()


def _write(tmp_path: Path, config: str, **files: str) -> Path:
    (tmp_path / "panel.toml").write_text(config)
    for name, text in files.items():
        (tmp_path / f"{name}.toml").write_text(text)
    return tmp_path


def test_an_object_is_put_into_the_task_file(tmp_path: Path) -> None:
    d = _write(tmp_path, '[[button]]\nid = "get"\nlabel = "Get"\ntask = "get.toml"\n'
               'objects = ["cup", "phone"]\nabout = "the {object}"\n',
               get='name = "get {object}"\n[[step]]\nwait = 1\n')  # fmt: skip
    (button,) = load_buttons(d)
    assert button.task("phone").name == "get phone"
    with pytest.raises(ConfigError, match=r"object 'spoon' is not one of \['cup', 'phone'\]"):
        button.task("spoon")


@pytest.mark.parametrize(
    ("config", "message"),
    [
        ("[[button]]\nid = 'a'\nlabel = 'A'\n", r"button 1: 'task' must be a non-empty string"),
        ("[[button]]\nid = 'a b'\nlabel = 'A'\ntask = 'a.toml'\n", r"button 1: id 'a b'"),
        (
            "[[button]]\nid = 'a'\nlabel = 'A'\ntask = 'a.toml'\ncolour = 1\n",
            r"button 1: unknown key\(s\) \['colour'\]",
        ),
        ("[[button]]\nid = 'a'\nlabel = 'A'\ntask = 'a.toml'\n" * 2, "used twice: a"),
        (
            "[[button]]\nid = 'a'\nlabel = 'A'\ntask = 'a.toml'\nsay = { hungry = 'x' }\n",
            "say must map troubles",
        ),
        ("button = 3\n", r"one \[\[button\]\] table per button"),
        ("[[button]\n", "not valid TOML"),
    ],
)
def test_a_bad_buttons_file_is_refused(tmp_path: Path, config: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message) as exc:
        load_buttons(_write(tmp_path, config))
    assert "panel.toml" in str(exc.value)


def test_a_broken_task_file_stops_the_panel_with_its_line(tmp_path: Path) -> None:
    d = _write(tmp_path, "[[button]]\nid = 'a'\nlabel = 'A'\ntask = 'a.toml'\n",
               a="[[step]]\nwait = 1\n[[step]]\ngripper = 400\n")  # fmt: skip
    with pytest.raises(ConfigError, match=r"a\.toml:4: step 2 \(gripper\)"):
        load_buttons(d)


# -- the page's model on the real cores ----------------------------------------------------------


def _press(ls: TaskLockStep, view: PanelView, button: TaskButton, task_id: str) -> SubmitReply:
    """What the panel does for a press: the submission, then the task's events."""
    view.on_submitting(button, "")
    seen = len(ls.events)
    reply = ls.submit(button.task(), task_id=task_id)
    view.on_submitted(button, "", reply)
    if reply.accepted:
        ls.run_while_busy()
    for event in ls.events[seen:]:
        view.on_event(event)
    return reply


def test_the_page_tells_the_real_stacks_reports_in_plain_words() -> None:
    buttons = {b.id: b for b in load_buttons(DEFAULT_DIR)}
    view = PanelView(list(buttons.values()))
    for service in ("sequencer", "controller", "can_bridge", "planner"):
        view.on_alive(service, True)
    ls = TaskLockStep()
    ls.start_arm()
    assert view.arm_words() == "Ready"
    # the arm starts folded: Home is refused, and so is Fold, each in its own words
    assert not _press(ls, view, buttons["home"], "t1").accepted
    assert view.snapshot()["notice"]["text"] == "The arm is folded. Press Unfold first."
    assert "planner refused" in view.snapshot()["notice"]["details"]
    assert not _press(ls, view, buttons["fold"], "t2").accepted
    assert view.snapshot()["notice"]["text"] == "The arm is already folded."
    # Unfold runs; its progress is told in words while it runs
    view.on_submitting(buttons["unfold"], "")
    reply = ls.submit(buttons["unfold"].task(), task_id="t3")
    ls.run_until_event("step_started")
    for event in ls.events:
        if event.task_id == "t3":
            view.on_event(event)
    assert view.arm_words() == "Busy: Unfold"
    assert view.task_words() == "Unfold: Unfolding"
    view.on_submitted(buttons["unfold"], "", reply)  # the answer may come after the events
    ls.run_while_busy()
    for event in ls.events:
        if event.task_id == "t3" and event.event != "accepted":
            view.on_event(event)
    assert view.snapshot()["notice"] == {"text": "Done: Unfold.", "details": "",
                                         "trouble": False}  # fmt: skip
    assert view.task is None and view.arm_words() == "Ready"
    # STOP during a task: the task fails, the page says STOP is on
    seen = len(ls.events)
    assert ls.submit(buttons["fold"].task(), task_id="t4").accepted
    ls.run_until_event("step_started")
    ls.ls.publish(ep.ESTOP, EStop(stamp_ns=ls.ls.t_ns, seq=0, engaged=True, source="panel"))
    ls.run_while_busy()
    failed = [e for e in ls.events[seen:] if e.event == "failed"]
    assert failed, [e.event for e in ls.events[seen:]]
    fresh = PanelView(list(buttons.values()))  # a panel that did not see the e-stop itself
    for service in ("sequencer", "controller", "can_bridge", "planner"):
        fresh.on_alive(service, True)
    for event in ls.events[seen:]:
        fresh.on_event(event)
    assert fresh.snapshot()["notice"]["text"] == sentence(Trouble.STOPPED)
    assert fresh.estop and fresh.arm_words() == "Stopped: STOP is on"
    # a task while the bridge is e-stopped is refused: STOP is on
    refused = ls.submit(buttons["unfold"].task(), task_id="t5")
    assert refusal_trouble(refused) is Trouble.STOPPED, refused.errors


def test_a_missing_service_and_a_busy_arm_are_told_plainly() -> None:
    ls = TaskLockStep()
    ls.start_arm()
    unfold = next(b for b in load_buttons() if b.id == "unfold")
    ls.seq.on_liveliness("planner", False, ls.ls.t_ns)
    missing = ls.submit(unfold.task(), task_id="a")
    assert refusal_trouble(missing) is Trouble.PARTS_MISSING, missing.errors
    ls.seq.on_liveliness("planner", True, ls.ls.t_ns)
    assert ls.submit(unfold.task(), task_id="b").accepted
    busy = ls.submit(unfold.task(), task_id="c")
    assert refusal_trouble(busy) is Trouble.BUSY, busy.errors


def test_a_task_of_another_client_is_shown_and_a_lost_end_is_caught() -> None:
    view = PanelView(load_buttons())
    view.on_event(TaskEvent(stamp_ns=1, seq=0, task_id="x", event="accepted", step=-1, total=2))
    view.on_event(TaskEvent(stamp_ns=2, seq=1, task_id="x", event="step_started", step=1,
                            total=2, kind="gripper"))  # fmt: skip
    assert view.task_words() == "A task: Moving the hand, step 2 of 2 (50 %)"
    view.on_status("x", "succeeded")  # its final event was lost on the way
    assert view.task is None


def test_the_panel_uses_the_supervisor_and_jog_apis_only() -> None:
    """Every endpoint the panel's modules name is one of its keys (the access control gives
    its identity those and no other), and each of them is a supervisor endpoint."""
    root = Path(__file__).resolve().parent.parent / "manus_stack" / "panel"
    named = {
        name
        for path in root.glob("*.py")
        if path.name != "keys.py"
        for name in re.findall(r"\bep\.([A-Z_]+)\b", path.read_text())
    }
    keys = {name for name in dir(ep) if getattr(ep, name) in PANEL_KEYS}
    assert named and named <= keys | {"SIM_TRUTH"}, named - keys  # the truth: the test rig
    assert all(key.audience is ep.Audience.SUPERVISOR for key in PANEL_KEYS)


def test_done_is_offered_while_a_follow_step_runs() -> None:
    """The drink's hold at the mouth ends when the person says so: the page offers Done
    while the running step is a follow step, and not while paused or at another step."""
    view = PanelView(load_buttons())
    assert view.snapshot()["task"] is None

    def event(seq: int, kind: str, step: int = 3, what: str = "step_started") -> None:
        view.on_event(TaskEvent(stamp_ns=seq, seq=seq, task_id="d", event=what, step=step,
                                total=7, kind=kind))  # fmt: skip

    event(0, "", -1, "accepted")
    event(1, "pick", 1)
    assert not view.can_finish() and not view.snapshot()["task"]["can_finish"]
    event(2, "follow")
    assert view.can_finish() and view.snapshot()["task"]["can_finish"]
    assert view.task_words() == "A task: Holding it for you, step 4 of 7 (43 %)"
    event(3, "follow", what="paused")
    assert not view.can_finish()
    event(4, "follow", what="resumed")
    assert view.can_finish()
    event(5, "place", 4)
    assert not view.can_finish()
