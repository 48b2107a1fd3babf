"""Shared fixtures: a loopback Zenoh router, settings for clients, Hypothesis profile."""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

from manus.session import ZenohSettings, client_settings, open_session, router_settings
from manus.validity import warm_up
from manus_stack.up import free_port

# Fixed seeds everywhere: the same examples on every run and in CI.
settings.register_profile(
    "manus",
    derandomize=True,
    deadline=None,
    max_examples=200,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.load_profile("manus")


def pytest_sessionstart(session: pytest.Session) -> None:
    """Compile the fast validity check's kernels before any test: a fresh checkout has
    an empty numba cache, and a service a test starts must not spend its start-up
    deadline compiling them (this fills the cache they load)."""
    warm_up()


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Tests marked ``slow`` run real processes in real time on a 2-core machine, where a
    scheduling stall now and then delays the 60 ms cycle past a deadline (seen about once
    in three full runs, never in isolation). They get one rerun; a real fault fails both
    runs, and pytest-rerunfailures reports every rerun in the summary ("R")."""
    for item in items:
        if item.get_closest_marker("slow") is not None:
            item.add_marker(pytest.mark.flaky(reruns=1, reruns_delay=1))


LOG_TAIL_LINES = 40
"""Lines of each child log shown when a slow test fails."""


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Iterator[None]:
    """When a ``slow`` test fails, print the tail of every log its processes wrote under
    its ``tmp_path`` (``logs/<service>.log`` of ``manus up``/``manus demo``, netns logs).

    Printed at once, not attached to the report: a failure that passes on its rerun is
    otherwise reported only as "R", and CI keeps nothing but what the run printed.
    """
    outcome = yield
    report = outcome.get_result()  # type: ignore[attr-defined]
    if report.when != "call" or not report.failed or item.get_closest_marker("slow") is None:
        return
    tmp = getattr(item, "funcargs", {}).get("tmp_path")
    reporter = item.config.pluginmanager.get_plugin("terminalreporter")
    if tmp is None or reporter is None:
        return
    logs = sorted(Path(tmp).rglob("*.log"))
    reporter.write_line("")
    reporter.write_sep("-", f"{item.nodeid} failed: {len(logs)} child log(s) under {tmp}")
    for log in logs:
        lines = log.read_text(errors="replace").splitlines()[-LOG_TAIL_LINES:]
        reporter.write_sep(".", f"{log.relative_to(tmp)} (last {len(lines)} lines)")
        for line in lines:
            reporter.write_line(line)


def eventually(check: Callable[[], bool], timeout: float = 10.0, what: str = "condition") -> None:
    """Poll ``check()`` every 10 ms until it holds; AssertionError naming ``what`` after
    ``timeout`` [s] (live tests: bounded waits, never a sleep that hopes)."""
    deadline = time.monotonic() + timeout
    while not check():
        assert time.monotonic() < deadline, f"{what} not met within {timeout} s"
        time.sleep(0.01)


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
