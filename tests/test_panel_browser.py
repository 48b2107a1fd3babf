"""``manus panel`` in a real browser (Debian's headless Chromium, driven by Playwright) on
the whole stack on the simulator, judged on the simulator's truth (``SimTruth.qd_true``).

One stack, one panel and one browser serve every test of this module (about a minute).
Fingers are real touches (Chromium's touch input, several at once), keys real key
presses. Skipped, saying what to install, where Chromium or Playwright is missing.
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

from manus.config import FOLDED_Q_DEG
from manus_stack.drink import DrinkSetting
from manus_stack.panel.browser import chromium, missing
from manus_stack.panel.freezing_proxy import FreezingProxy
from manus_stack.panel.rig import STILL_RAD_S, PanelRig, floor_ms, recover, stop_bound_ms
from manus_stack.panel.touch import Fingers
from schemas.objects import ObjectTruth

if TYPE_CHECKING:
    from playwright.sync_api import BrowserContext, Page

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(missing() is not None, reason=f"browser tests: {missing()}"),
]

TASK_BUTTONS = [
    ("unfold", "folded"),
]
"""Task buttons pressed in the browser, each with the arm's pose before it runs (Drink:
the module's last test)."""

TASK_TIMEOUT_S = 60.0
DRINK_TIMEOUT_S = 240.0
"""The drink: about 95 s of motion and the task's 20 s at the mouth, on a loaded machine."""


@pytest.fixture(scope="module")
def rig(tmp_path_factory: pytest.TempPathFactory) -> Iterator[PanelRig]:
    """The stack with the drink demo's seed-0 setting: a cup on the table (the camera sees
    it), the user's mouth swaying and tracked (the drink follows it)."""
    run_dir = tmp_path_factory.mktemp("panel")
    objects, config = DrinkSetting.drawn(0).write(run_dir)
    with PanelRig(run_dir, objects=str(objects), sim_args=("--config", str(config))) as started:
        started.start()
        yield started


@pytest.fixture(scope="module")
def browser() -> Iterator[BrowserContext]:
    with chromium() as context:
        yield context


def open_page(rig: PanelRig, browser: BrowserContext, query: str = "", url: str = "") -> Page:
    page = browser.new_page()
    page.goto((url or rig.url) + query)
    page.wait_for_selector("#pad-up")  # the server's hello came
    page.wait_for_function("['Ready', 'Paused'].some(w => document.getElementById('arm')"
                           ".textContent.startsWith(w))"
                           " || document.getElementById('arm').textContent.startsWith('Stopped')",
                           timeout=30_000)  # fmt: skip
    return page


@pytest.fixture
def page(rig: PanelRig, browser: BrowserContext) -> Iterator[Page]:
    opened = open_page(rig, browser)
    yield opened
    if not opened.is_closed():
        opened.close()


def folded(rig: PanelRig) -> bool:
    truth = rig.latest()
    assert truth is not None
    return all(
        abs(math.degrees(q) - f) < 5.0 for q, f in zip(truth.q_true, FOLDED_Q_DEG, strict=True)
    )


def wait_done(page: Page, label: str, timeout_s: float = TASK_TIMEOUT_S) -> None:
    """Wait until the page says the task ``label`` is done; fail with what it says instead
    when the task failed (under heavy load the stack's own deadmen can stop a task:
    docs/deployment.md, Faults)."""
    done = f"Done: {label}."
    page.wait_for_function(
        "(() => { const n = document.getElementById('notice');"
        f" const text = document.getElementById('notice-text').textContent;"
        f" return !n.hidden && (text === {done!r} || !n.classList.contains('good')); }})()",
        timeout=timeout_s * 1000,
    )
    said = page.text_content("#notice-text")
    assert said == done, f"{said!r}: {page.text_content('#notice-details')}"


def run_task(page: Page, button: str) -> None:
    label = page.text_content(f"#task-{button}")
    assert label
    page.click(f"#task-{button}")
    wait_done(page, label)


def arm_to(rig: PanelRig, page: Page, pose: str) -> None:
    """Bring the arm to ``pose`` (folded, unfolded) with the panel's own buttons (after a
    failed test, :func:`recover` first, so that one failure does not fail the rest)."""
    notice = page.locator("#notice")
    if notice.is_visible() and "good" not in (notice.get_attribute("class") or ""):
        recover(page)
    if pose == "folded" and not folded(rig):
        run_task(page, "fold")
    if pose == "unfolded" and folded(rig):
        run_task(page, "unfold")
    assert folded(rig) == (pose == "folded")


def report(what: str, elapsed_ms: float, speed: float) -> None:
    print(f"\n{what}: true speeds at rest {elapsed_ms:.0f} ms after it (moving "
          f"{math.degrees(speed):.1f} deg/s; floor {floor_ms(speed):.0f} ms, bound "
          f"{stop_bound_ms(speed):.0f} ms)")  # fmt: skip


@pytest.mark.parametrize(("button", "start"), TASK_BUTTONS)
def test_a_task_button_runs_its_task(rig: PanelRig, page: Page, button: str, start: str) -> None:
    arm_to(rig, page, start)
    label = page.text_content(f"#task-{button}")
    page.click(f"#task-{button}")
    rig.wait_moving(timeout=30.0)
    assert page.text_content("#arm") == f"Busy: {label}"
    failures = colour_failures(page, "a task running")
    assert not failures, "\n".join(failures)
    assert label
    wait_done(page, label)
    assert page.text_content("#arm") == "Ready"
    assert rig.speed() < STILL_RAD_S


def test_a_task_pauses_when_its_last_page_closes(rig: PanelRig, browser: BrowserContext) -> None:
    """Nobody could press STOP any more: the task the panel started pauses (the arm comes
    to rest), and a new page resumes it."""
    page = open_page(rig, browser)
    arm_to(rig, page, "unfolded")
    fingers = Fingers(page)
    rig.hold_until_moving(fingers, "up")
    time.sleep(1.0)  # away from home, so that Home moves
    fingers.lift(1)
    rig.still_since(time.time_ns())
    page.click("#task-home")
    rig.wait_moving(timeout=30.0)
    closed = time.time_ns()
    page.close()
    at_rest, _ = rig.still_since(closed, timeout=5.0)
    print(f"\nlast page closed mid-task: at rest {(at_rest - closed) / 1e6:.0f} ms after")
    again = open_page(rig, browser)
    try:
        said = again.locator("#arm")
        deadline = time.monotonic() + 10.0
        while said.text_content() != "Paused: Home" and time.monotonic() < deadline:
            time.sleep(0.05)
        if said.text_content() != "Paused: Home":  # shown with -s also when rerun
            print(f"\nnot paused: {said.text_content()!r}, {again.text_content('#notice')!r}")
        assert said.text_content() == "Paused: Home", again.text_content("#notice")
        again.click("#resume")
        wait_done(again, "Home")
    finally:
        again.close()


def test_stop_brings_the_true_joint_speeds_to_zero(rig: PanelRig, page: Page) -> None:
    arm_to(rig, page, "unfolded")
    fingers = Fingers(page)
    rig.hold_until_moving(fingers, "up")
    pressed = fingers.press(2, "#stop")  # a second finger, while the first holds the pad
    at_rest, speed = rig.still_since(pressed)
    elapsed = (at_rest - pressed) / 1e6
    report("STOP", elapsed, speed)
    assert elapsed <= stop_bound_ms(speed)
    fingers.lift(2)
    page.wait_for_selector("#release-stop", state="visible")
    assert page.text_content("#arm") == "Stopped: STOP is on"
    # STOP holds: the finger still on the pad, a new press of it, nothing moves
    fingers.lift(1)
    fingers.press(1, "#pad-up")
    time.sleep(0.6)
    fingers.lift(1)
    assert max(abs(v) for _, t in rig.truths[-8:] for v in t.qd_true) < STILL_RAD_S
    page.click("#release-stop")
    page.wait_for_selector("#release-stop", state="hidden")


def test_closing_the_tab_mid_jog_stops_the_arm(rig: PanelRig, browser: BrowserContext) -> None:
    page = open_page(rig, browser)
    arm_to(rig, page, "unfolded")
    rig.hold_until_moving(Fingers(page), "down")
    closed = time.time_ns()
    page.close()
    at_rest, speed = rig.still_since(closed)
    elapsed = (at_rest - closed) / 1e6
    report("tab closed", elapsed, speed)
    assert elapsed <= stop_bound_ms(speed)


def test_the_keyboard_holds_a_pad_button(rig: PanelRig, page: Page) -> None:
    """A key held on the focused pad button moves the arm; released, the arm stops."""
    arm_to(rig, page, "unfolded")
    page.focus("#pad-back")
    for attempt in range(3):  # a jog stopped by an earlier test wants a release first
        page.keyboard.down("Enter")
        try:
            rig.wait_moving(timeout=2.0)
            break
        except TimeoutError:
            page.keyboard.up("Enter")
            assert attempt < 2, "Enter held on Back never moved the arm"
    released = time.time_ns()
    page.keyboard.up("Enter")
    at_rest, speed = rig.still_since(released)
    report("key released", (at_rest - released) / 1e6, speed)
    assert (at_rest - released) / 1e6 <= stop_bound_ms(speed)


def test_a_silent_network_stops_the_arm(rig: PanelRig, browser: BrowserContext) -> None:
    proxy = FreezingProxy(rig.port)
    try:
        page = open_page(rig, browser, url=f"http://127.0.0.1:{proxy.port}/")
        arm_to(rig, page, "unfolded")
        fingers = Fingers(page)
        rig.hold_until_moving(fingers, "up")
        silent = time.time_ns()
        proxy.freeze()  # the finger stays on the button; nothing gets through
        at_rest, speed = rig.still_since(silent)
        elapsed = (at_rest - silent) / 1e6
        report("network silent", elapsed, speed)
        assert elapsed <= stop_bound_ms(speed)
        time.sleep(0.7)
        back = time.time_ns()
        proxy.frozen.clear()  # the late commands arrive all at once: refused, still at rest
        time.sleep(0.8)
        late = [t for rx, t in rig.truths if rx > back]
        assert late and max(abs(v) for t in late for v in t.qd_true) < STILL_RAD_S
        fingers.lift(1)
        page.close()
    finally:
        proxy.close()


def test_scanning_reaches_every_button(rig: PanelRig, browser: BrowserContext) -> None:
    page = open_page(rig, browser, "?scan=1&scan_ms=250")
    arm_to(rig, page, "unfolded")
    page.evaluate(
        """() => { window.seen = new Set();
        new MutationObserver(() => { const el = document.querySelector('.scan-focus');
            if (el) window.seen.add(el.id); })
        .observe(document.body, {subtree: true, attributes: true, attributeFilter: ['class']}); }"""
    )
    buttons: list[str] = page.evaluate(
        "[...document.querySelectorAll('button')]"
        ".filter(b => !b.disabled && b.offsetParent !== null).map(b => b.id)"
    )
    assert {"stop", "task-unfold", "pad-up", "scan"} <= set(buttons)
    page.wait_for_function(f"{list(buttons)}.every(id => window.seen.has(id))", timeout=30_000)
    # the switch (Space) on the highlighted "Faster" (or "Slower" at the top level): the
    # level changes; on the other, it changes back
    first, then = ("faster", "slower") if "faster" in buttons else ("slower", "faster")
    level = page.text_content("#level")
    _switch_when_highlighted(page, first, ("keydown", "keyup"))
    page.wait_for_function(f"document.getElementById('level').textContent !== '{level}'")
    _switch_when_highlighted(page, then, ("keydown", "keyup"))
    page.wait_for_function(f"document.getElementById('level').textContent === '{level}'")
    # held on a pad button, the switch moves the arm; let go, it stops
    for attempt in range(3):  # a jog stopped by an earlier test wants a release first
        _switch_when_highlighted(page, "pad-forward", ("keydown",))
        try:
            rig.wait_moving(timeout=2.0)
            break
        except TimeoutError:
            _switch(page, "keyup")
            assert attempt < 2, "the switch held on Forward never moved the arm"
    released = time.time_ns()
    _switch(page, "keyup")
    at_rest, speed = rig.still_since(released)
    report("switch released", (at_rest - released) / 1e6, speed)
    page.close()


_SWITCH_ON_HIGHLIGHT = """([id, types]) => new Promise((resolve) => {
    const el = document.getElementById(id);
    const press = () => {
        for (const type of types) {
            window.dispatchEvent(new KeyboardEvent(type, {code: "Space", key: " "}));
        }
        resolve();
    };
    if (el.classList.contains("scan-focus")) return press();
    const seen = new MutationObserver(() => {
        if (el.classList.contains("scan-focus")) { seen.disconnect(); press(); }
    });
    seen.observe(el, {attributes: true, attributeFilter: ["class"]});
})"""
"""The switch pressed in the page the moment the scan highlights a control: the observer
runs right after the step that highlighted it, before the next step can move on (a key
sent from the test, across the browser's protocol, can land a step later on a loaded
machine: on another control, STOP included)."""


def _switch_when_highlighted(page: Page, element_id: str, types: tuple[str, ...]) -> None:
    page.wait_for_selector(f"#{element_id}", timeout=30_000)
    page.evaluate(_SWITCH_ON_HIGHLIGHT, [element_id, list(types)])


def _switch(page: Page, event_type: str) -> None:
    """The switch's key event now (a release: the scan waits while it is held)."""
    page.evaluate(
        "(type) => window.dispatchEvent(new KeyboardEvent(type, {code: 'Space', key: ' '}))",
        event_type,
    )


def _contrast(a: list[float], b: list[float]) -> float:
    def lum(rgb: list[float]) -> float:
        c = [v / 255 for v in rgb[:3]]
        lin = [v / 12.92 if v <= 0.04045 else ((v + 0.055) / 1.055) ** 2.4 for v in c]
        return 0.2126 * lin[0] + 0.7152 * lin[1] + 0.0722 * lin[2]

    hi, lo = sorted((lum(a), lum(b)), reverse=True)
    return (hi + 0.05) / (lo + 0.05)


COLOURS_JS = Path(__file__).with_name("panel_colours.js").read_text()
"""Collects every visible text's colour and the colour behind it, and every button's edge."""


def colour_failures(page: Page, state: str) -> list[str]:
    """Text 4.5:1 (3:1 when large: 24 px, or 18.66 px bold), a button's edge against what
    is behind it and the focus ring 3:1 (WCAG 2.1 1.4.3 and 1.4.11), as rendered now."""
    failures: list[str] = []
    found: dict[str, Any] = page.evaluate(COLOURS_JS)
    assert found["texts"], state
    for item in found["texts"]:
        large = item["size"] >= 24 or (item["size"] >= 18.66 and item["weight"] >= 700)
        need = 3.0 if large else 4.5
        ratio = _contrast(item["fg"], item["bg"])
        if ratio < need:
            failures.append(f"{state}: {item['what']!r} {ratio:.2f} < {need}")
    for item in found["edges"]:
        ratio = _contrast(item["edge"], item["bg"])
        if ratio < 3.0:
            failures.append(f"{state}: edge of #{item['id']} {ratio:.2f} < 3")
    return failures


def test_every_colour_meets_wcag_aa(rig: PanelRig, page: Page) -> None:
    """In every state the page shows: idle, a trouble, STOP on, a held pad button, the
    scanning highlight (a running task: in the task button's test)."""
    failures = colour_failures(page, "idle")
    page.click("#stop")
    page.wait_for_selector("#release-stop", state="visible")
    failures += colour_failures(page, "STOP on")
    page.click("#task-home")  # STOP is on: a trouble
    page.wait_for_selector("#notice", state="visible")
    failures += colour_failures(page, "trouble")
    page.click("#release-stop")
    page.wait_for_selector("#release-stop", state="hidden")
    fingers = Fingers(page)
    fingers.press(1, "#pad-left")
    page.wait_for_selector("#pad-left.held")
    failures += colour_failures(page, "pad held")
    fingers.lift(1)
    page.click("#scan")
    page.wait_for_selector(".scan-focus")
    failures += colour_failures(page, "scanning")
    assert not failures, "\n".join(failures)


@pytest.mark.timeout(240)  # the drink takes 70 s of real time, more on a loaded machine
def test_pressing_drink_runs_the_task_on_the_simulator(rig: PanelRig, page: Page) -> None:
    """The whole drink (docs/drink.md): the cup from the table to the swaying mouth, held
    there until the person presses Done (the task alone would hold for 20 s), back on the
    table, folded; judged on the truth. From the unfolded arm, where the module's tests
    before it leave it: its fold-out step is then over at once (folding the arm first
    only to unfold it again cost 16 s; the fold-out from the folded arm is the Unfold
    button's test). Last in the module: a drink stopped half-way leaves the arm where the
    panel's Fold cannot plan from."""
    arm_to(rig, page, "unfolded")
    cup_before = _cup(rig)
    start = rig.latest()
    assert start is not None
    assert page.locator("#done").is_hidden()
    page.click("#task-drink")
    rig.wait_moving(timeout=30.0)
    assert page.text_content("#arm") == "Busy: Drink"
    # Done shows with the follow step (4 of 7); the step's progress starts once the cup
    # holds at the mouth: 44 % of the task is a little of that hold. (A task that ends
    # before, failed, ends the waits: wait_done says why.)
    page.wait_for_function(
        "document.getElementById('task').hidden"
        " || Number(document.getElementById('task-bar').getAttribute('aria-valuenow')) >= 44",
        timeout=DRINK_TIMEOUT_S * 1000,
    )
    if page.locator("#task").is_hidden():
        wait_done(page, "Drink", 1.0)  # says why it ended
        pytest.fail("the drink ended before it held at the mouth")
    assert page.locator("#done").is_visible()
    words = page.text_content("#task-words") or ""
    assert words.startswith("Drink: Holding it for you, step 4 of 7"), words
    page.click("#done")
    # the hold ends at the person's word, long before the task's own 20 s
    page.wait_for_function("document.getElementById('done').hidden", timeout=10_000)
    assert "step 4 of 7" not in (page.text_content("#task-words") or "")
    wait_done(page, "Drink", DRINK_TIMEOUT_S)
    assert page.text_content("#arm") == "Ready", rig.story()
    truth = rig.latest()
    assert truth is not None and folded(rig), rig.story()
    assert truth.contacts == start.contacts, rig.story()  # counted since the simulator started
    assert truth.held_min_person is not None and truth.held_min_person > 0.050
    assert truth.min_person_clearance is not None and truth.min_person_clearance > 0.050
    cup = _cup(rig)
    assert not cup.held and cup.resting_on == "table"
    assert math.dist(cup.xyz[:2], cup_before.xyz[:2]) < 0.010


def _cup(rig: PanelRig) -> ObjectTruth:
    truth = rig.latest()
    assert truth is not None
    return next(o for o in truth.objects if o.id == "cup")
