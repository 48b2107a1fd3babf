"""Shared fixtures: a loopback Zenoh router, settings for clients, Hypothesis profile."""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterator
from typing import Any

import pytest
import zenoh
from hypothesis import HealthCheck, settings

from manus.session import ZenohSettings, client_settings, open_session, router_settings
from manus.validity import warm_up
from manus_stack.ports import free_port
from tests import live_priority, scheduling
from tests.run_report import (
    pytest_runtest_makereport,
    pytest_sessionfinish,
    pytest_terminal_summary,
)
from tests.scheduling import LiveApartScheduling

__all__ = ["pytest_runtest_makereport", "pytest_sessionfinish", "pytest_terminal_summary"]

# Fixed seeds everywhere: the same examples on every run and in CI.
settings.register_profile(
    "manus",
    derandomize=True,
    deadline=None,
    max_examples=200,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.load_profile("manus")


pytest_xdist_auto_num_workers = pytest.hookimpl(optionalhook=True)(scheduling.workers)
pytest_configure = scheduling.pytest_configure
pytest_unconfigure = scheduling.pytest_unconfigure


@pytest.hookimpl(tryfirst=True)  # in the controlling process, before it starts workers
def pytest_sessionstart(session: pytest.Session) -> None:
    """Compile the fast validity check's kernels before any test: a fresh checkout has
    an empty numba cache, and a service a test starts must not spend its start-up
    deadline compiling them (this fills the cache they load)."""
    warm_up()


@pytest.hookimpl(optionalhook=True)
def pytest_xdist_make_scheduler(config: pytest.Config, log: Any) -> LiveApartScheduling:
    """The live tests apart from the pure ones (:mod:`tests.scheduling`)."""
    return LiveApartScheduling(config, log)


_NICE = os.getpriority(os.PRIO_PROCESS, 0)  # a worker's PURE_NICE comes later: pure only


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_setup(item: pytest.Item) -> Iterator[None]:
    """A live test's process at a real-time priority while it runs (tests/live_priority.py)."""
    if item.get_closest_marker("slow") is not None:
        live_priority.enter(item)
    yield
    if item.get_closest_marker("slow") is not None:
        live_priority.started(item)


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_teardown(item: pytest.Item) -> Iterator[None]:
    """... and ordinary again after it."""
    yield
    if item.get_closest_marker("slow") is not None:
        live_priority.leave(_NICE)


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Tests marked ``slow`` run real processes in real time: in a few lanes at once
    (:mod:`tests.scheduling`), and with one rerun, so that a failure tells whether it
    repeats; a run with a rerun still fails (:mod:`tests.run_report`)."""
    if not os.environ.get(LIVE_DRINK):
        for item in items:
            if item.get_closest_marker("live_drink") is not None:
                item.add_marker(pytest.mark.skip(reason=LIVE_DRINK_SKIP))
    live = [item for item in items if item.get_closest_marker("slow") is not None]
    for item in live:
        item.add_marker(pytest.mark.flaky(reruns=1, reruns_delay=1))
    scheduling.tell_live(config, live)


LIVE_DRINK = "MANUS_TEST_LIVE_DRINK"
"""Environment variable: 1 runs the live drink tests (marker ``live_drink``)."""
LIVE_DRINK_SKIP = (
    "`manus demo drink` through the CLI takes about 90 s of real time and repeats what the "
    "panel's live drink test (tests/test_panel_browser.py) and `manus bench drink` (lock-step) "
    f"check; set {LIVE_DRINK}=1 to run it (docs/testing.md)"
)


def eventually(check: Callable[[], bool], timeout: float = 10.0, what: str = "condition") -> None:
    """Poll ``check()`` every 10 ms until it holds; AssertionError naming ``what`` after
    ``timeout`` [s] (live tests: bounded waits, never a sleep that hopes)."""
    deadline = time.monotonic() + timeout
    while not check():
        assert time.monotonic() < deadline, f"{what} not met within {timeout} s"
        time.sleep(0.01)


def progressing(
    count: Callable[[], int], total: int, idle: float = 10.0, what: str = "items"
) -> None:
    """Poll ``count()`` until it reaches ``total``; AssertionError naming ``what`` and how
    far it got once it has not grown for ``idle`` [s]. A wait for work that a loaded machine
    does slowly but surely (a recorder writing thousands of messages): bounded by progress,
    so a slow run passes and a stalled one (a message lost, a thread stuck) fails."""
    last, since = -1, time.monotonic()
    while (n := count()) < total:
        if n != last:
            last, since = n, time.monotonic()
        assert time.monotonic() - since < idle, f"{what}: {n} of {total}, none more in {idle} s"
        time.sleep(0.01)


def matched_publisher(
    session: zenoh.Session, key: str, timeout: float = 10.0, *, block: bool = False
) -> zenoh.Publisher:
    """A publisher on ``key`` once a subscriber matches it (bounded by ``timeout`` [s]);
    ``block``: it waits for room in a full queue instead of dropping (a burst under load).

    Zenoh routes a sample by what the router knows when it arrives: a subscription
    declared a moment ago on another session travels on another link and may reach the
    router after a sample sent at once, which is then dropped, never redelivered. A test
    that publishes to a service it just started publishes once the router has told this
    session about the subscription (the publisher's matching status)."""
    congestion = zenoh.CongestionControl.BLOCK if block else zenoh.CongestionControl.DROP
    pub = session.declare_publisher(key, congestion_control=congestion)
    eventually(lambda: bool(getattr(pub.matching_status, "matching", False)), timeout,
               f"a subscriber of {key}")  # fmt: skip
    return pub


@pytest.fixture
def router_endpoint() -> Iterator[str]:
    """A Zenoh router on a fresh loopback port, for the duration of one test."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    session = open_session(router_settings(endpoint))
    try:
        yield endpoint
    finally:
        session.close()


@pytest.fixture
def zenoh_settings(router_endpoint: str) -> ZenohSettings:
    """Client settings for the test's router, with a prefix of its own."""
    return client_settings(router_endpoint, prefix="test")
