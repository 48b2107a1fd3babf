"""A headless Chromium for the panel's screenshots and browser tests.

Debian's Chromium (``apt-get install -y chromium``: ``/usr/bin/chromium``), driven by
Playwright for Python (the ``playwright`` package of the ``test`` extra). Playwright's own
browser download (``playwright install``) is never used: it fetches a browser build from
outside the package registries. Each launch gets a fresh profile directory and the flags
of :data:`FLAGS` (no sandbox: it runs as root in CI; nothing from the network but the
page).
"""

from __future__ import annotations

import shutil
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

from manus.errors import ManusError

if TYPE_CHECKING:
    from playwright.sync_api import BrowserContext

CHROMIUM = Path("/usr/bin/chromium")
"""Debian's Chromium."""
FLAGS = (
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
)
"""Chromium's flags: headless, no GPU, no network of its own."""
INSTALL = (
    "the panel's browser: Debian's Chromium (`apt-get install -y chromium`, as .ci/run does) "
    "and Playwright for Python (`pip install -e '.[test]'`; never `playwright install`)"
)
"""What to install when :func:`missing` says something is."""


class BrowserMissingError(ManusError):
    """Chromium or Playwright is not installed (the message says what to install)."""


def missing() -> str | None:
    """What is missing to drive the browser (None: nothing)."""
    if not CHROMIUM.is_file() and shutil.which("chromium") is None:
        return f"no {CHROMIUM}: install {INSTALL}"
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return f"no playwright package: install {INSTALL}"
    return None


@contextmanager
def chromium(width: int = 1024, height: int = 768, touch: bool = True) -> Iterator[BrowserContext]:
    """A browser context of a fresh headless Chromium, pages ``width`` x ``height`` CSS px,
    with a touch screen (``touch``) besides the mouse and the keyboard.

    Raises:
        BrowserMissingError: Chromium or Playwright is not installed.
    """
    why = missing()
    if why is not None:
        raise BrowserMissingError(why)
    from playwright.sync_api import sync_playwright

    executable = str(CHROMIUM) if CHROMIUM.is_file() else shutil.which("chromium")
    with sync_playwright() as p, tempfile.TemporaryDirectory(prefix="manus-chromium-") as profile:
        context = p.chromium.launch_persistent_context(
            profile,
            executable_path=executable,
            headless=True,
            args=list(FLAGS),
            viewport={"width": width, "height": height},
            has_touch=touch,
        )
        try:
            yield context
        finally:
            context.close()
