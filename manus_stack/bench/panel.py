"""``manus bench panel``: how fast the panel stops the arm, judged on the simulator's truth.

The whole stack on the simulator with ``manus panel`` (:class:`PanelRig`) and Debian's
headless Chromium (:mod:`manus_stack.panel.browser`); the arm unfolded, level 1. Each
trial holds a pad button with a real touch until the arm moves at speed, then stops it
one way, and measures from that moment to the first truth (``SimTruth``, once a cycle)
with every true joint speed under 0.5 deg/s:

- ``stop``: STOP pressed by a second finger, the first still on the pad;
- ``release``: the finger lifted;
- ``tab_closed``: the page closed;
- ``network_silent``: the link between the page and the panel goes silent (a loopback
  relay that stops carrying bytes and keeps the connection open): the controller's jog
  deadman stops the arm.

Each is given with the protocol's floor and the bound the browser tests hold it to
(:func:`~manus_stack.panel.rig.stop_bound_ms`: deadman + floor + the truth's period) and
how many trials went over it. Needs Chromium and Playwright (it says what to install).
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from manus_stack.panel.browser import chromium
from manus_stack.panel.freezing_proxy import FreezingProxy
from manus_stack.panel.rig import PanelRig, floor_ms, recover, stop_bound_ms
from manus_stack.panel.touch import Fingers

if TYPE_CHECKING:
    from playwright.sync_api import BrowserContext, Page

PADS = ("up", "down")
"""Trials go up and down in turn, so that the arm stays where it started."""


def _open(browser: BrowserContext, url: str) -> Page:
    page = browser.new_page()
    page.goto(url)
    page.wait_for_function("document.getElementById('arm').textContent === 'Ready'",
                           timeout=30_000)  # fmt: skip
    return page


def _unfold(page: Page, tries: int = 3) -> None:
    """Press Unfold until the page says it is done.

    Raises:
        RuntimeError: it never was, with what the page said.
    """
    said = ""
    for _ in range(tries):
        page.click("#task-unfold")
        page.wait_for_function(
            "(() => { const n = document.getElementById('notice'); return !n.hidden &&"
            " (n.classList.contains('good') || n.textContent.trim() !== ''); })()",
            timeout=60_000,
        )
        said = str(page.text_content("#notice-text"))
        if said == "Done: Unfold.":
            return
        recover(page)  # held stopped after a fault at start-up (load): what a helper does
    raise RuntimeError(f"Unfold did not run: {said!r}: {page.text_content('#notice-details')}")


def _trial(rig: PanelRig, page: Page, pad: str, stop: Callable[[Fingers], int]) -> list[float]:
    """One trial: [ms to rest, the speed at the stop [rad/s], its floor, its bound];
    ``stop`` stops the arm and returns when it acted [ns]."""
    fingers = Fingers(page)
    rig.hold_until_moving(fingers, pad)
    at = stop(fingers)
    rest, speed = rig.still_since(at)
    if not page.is_closed():
        for finger in list(fingers.down):
            fingers.lift(finger)
    return [(rest - at) / 1e6, speed, floor_ms(speed), stop_bound_ms(speed)]


def _figures(trials: list[list[float]]) -> dict[str, Any]:
    a = np.asarray(trials)
    return {
        "trials": len(trials),
        "at_rest_ms": {
            "p50": round(float(np.median(a[:, 0])), 1),
            "max": round(float(a[:, 0].max()), 1),
        },
        "speed_deg_s_p50": round(float(np.degrees(np.median(a[:, 1]))), 1),
        "floor_ms_p50": round(float(np.median(a[:, 2])), 1),
        "over_bound": int((a[:, 0] > a[:, 3]).sum()),
    }


def _press_stop(fingers: Fingers) -> int:
    return fingers.press(2, "#stop")  # a second finger, the first still on the pad


def _lift(fingers: Fingers) -> int:
    return fingers.lift(1)


def _close(fingers: Fingers) -> int:
    at = time.time_ns()
    fingers.page.close()
    return at


def _silence(proxy: FreezingProxy) -> Callable[[Fingers], int]:
    def freeze(fingers: Fingers) -> int:
        at = time.time_ns()
        proxy.freeze()
        return at

    return freeze


def run(quick: bool = False) -> dict[str, Any]:
    """The stop figures, ``quick``: 3 trials of each (else 10)."""
    n = 3 if quick else 10
    out: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix="manus-bench-panel-") as run_dir:
        rig = PanelRig(Path(run_dir), prefix="benchpanel")
        proxy: FreezingProxy | None = None
        try:
            rig.start()
            proxy = FreezingProxy(rig.port)
            with chromium() as browser:
                page = _open(browser, rig.url)
                _unfold(page)
                results: dict[str, list[list[float]]] = {
                    "stop": [], "release": [], "tab_closed": [], "network_silent": [],
                }  # fmt: skip
                for i in range(n):
                    pad, back = PADS[i % 2], PADS[1 - i % 2]
                    results["stop"].append(_trial(rig, page, pad, _press_stop))
                    page.click("#release-stop")
                    page.wait_for_selector("#release-stop", state="hidden")
                    time.sleep(1.0)  # the bridge back in running
                    results["release"].append(_trial(rig, page, back, _lift))
                    other = _open(browser, rig.url)
                    results["tab_closed"].append(_trial(rig, other, pad, _close))
                    silent = _open(browser, f"http://127.0.0.1:{proxy.port}/")
                    results["network_silent"].append(_trial(rig, silent, back, _silence(proxy)))
                    time.sleep(0.5)
                    silent.close()
                    proxy.frozen.clear()
                    time.sleep(0.5)
                out = {kind: _figures(trials) for kind, trials in results.items()}
        finally:
            if proxy is not None:
                proxy.close()
            rig.stop()
    return out
