"""Real touches on a page of the panel (Chromium's touch input, several fingers at once):
a finger goes down on an element and stays there until it is lifted, as a person holds a
pad button while another finger presses STOP."""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from playwright.sync_api import CDPSession, Page


class Fingers:
    """Touches on ``page`` (its browser context made with a touch screen).

    Args:
        page: the page.
    """

    def __init__(self, page: Page) -> None:
        self.page = page
        self.cdp: CDPSession = page.context.new_cdp_session(page)
        self.down: dict[int, dict[str, float]] = {}

    def press(self, finger: int, selector: str) -> int:
        """Put ``finger`` down on the middle of the element ``selector``; the wall clock
        just before it touches [ns] (after the element was found on the page)."""
        box = self.page.locator(selector).bounding_box()
        if box is None:
            raise ValueError(f"{selector} is not on the page")
        self.down[finger] = {"x": box["x"] + box["width"] / 2, "y": box["y"] + box["height"] / 2}
        points = [{**xy, "id": i} for i, xy in self.down.items()]
        at = time.time_ns()
        self.cdp.send("Input.dispatchTouchEvent", {"type": "touchStart", "touchPoints": points})
        return at

    def lift(self, finger: int) -> int:
        """Lift ``finger``; the wall clock just before [ns]."""
        point = {**self.down.pop(finger), "id": finger}
        at = time.time_ns()
        self.cdp.send("Input.dispatchTouchEvent", {"type": "touchEnd", "touchPoints": [point]})
        return at
