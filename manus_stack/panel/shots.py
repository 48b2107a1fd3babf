"""Screenshots of every screen of the panel, for docs/panel.md:

    python -m manus_stack.panel.shots --out docs/img      # about 30 s

Starts the whole stack on the simulator and ``manus panel`` (:class:`PanelRig`), opens the
page in Debian's headless Chromium (:mod:`manus_stack.panel.browser`) and goes through
what a user sees, saving ``panel_<screen>.png`` for each: a task refused in plain words
(the arm folded), a task running, the arm ready after it, moving it by hand, STOP on, the
choice of an object, switch scanning, and the page on a phone.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path
from typing import TYPE_CHECKING

from manus_stack.panel.browser import chromium
from manus_stack.panel.rig import PanelRig
from manus_stack.panel.touch import Fingers

if TYPE_CHECKING:
    from playwright.sync_api import Page

PHONE = (390, 844)
"""A phone's page size [CSS px]."""


def _text_is(page: Page, element: str, text: str, timeout_s: float = 60.0) -> None:
    page.wait_for_function(
        f"document.getElementById({element!r}).textContent === {text!r}",
        timeout=timeout_s * 1000,
    )


def take(out: Path) -> list[Path]:
    """Take every screenshot into ``out``; the files written."""
    out.mkdir(parents=True, exist_ok=True)
    run = tempfile.TemporaryDirectory(prefix="manus-panel-shots-")
    with run, PanelRig(Path(run.name)) as rig:
        rig.start()
        with chromium() as browser:
            page = browser.new_page()
            page.goto(rig.url)
            _text_is(page, "arm", "Ready")
            page.click("#task-home")  # the arm is folded after power-up
            page.wait_for_selector("#notice", state="visible")
            page.screenshot(path=str(out / "panel_trouble.png"))
            page.click("#task-unfold")
            rig.wait_moving(timeout=30.0)
            page.wait_for_timeout(2500)
            page.screenshot(path=str(out / "panel_task.png"))
            _text_is(page, "notice-text", "Done: Unfold.")
            page.screenshot(path=str(out / "panel_ready.png"))
            fingers = Fingers(page)
            fingers.press(1, "#pad-up")  # held, while a second finger presses STOP
            page.wait_for_timeout(1200)
            page.screenshot(path=str(out / "panel_jog.png"))
            fingers.press(2, "#stop")
            fingers.lift(2)
            fingers.lift(1)
            page.wait_for_selector("#release-stop", state="visible")
            page.screenshot(path=str(out / "panel_stop.png"))
            page.click("#release-stop")
            page.wait_for_selector("#release-stop", state="hidden")
            page.click("#task-fetch")
            page.wait_for_selector("#object-cup")
            page.screenshot(path=str(out / "panel_fetch.png"))
            page.click("#object-back")
            page.click("#scan")
            page.wait_for_selector("#task-unfold.scan-focus", timeout=30_000)
            page.screenshot(path=str(out / "panel_scanning.png"))
            page.close()
        with chromium(*PHONE) as phone:
            page = phone.new_page()
            page.goto(rig.url)
            _text_is(page, "arm", "Ready")
            page.screenshot(path=str(out / "panel_phone.png"), full_page=True)
    names = ("trouble", "task", "ready", "jog", "stop", "fetch", "scanning", "phone")
    return [out / f"panel_{name}.png" for name in names]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", default="docs/img", help="where to write (docs/img)")
    args = parser.parse_args()
    for path in take(Path(args.out)):
        print(path)


if __name__ == "__main__":
    main()
