"""What the end of a run says: the reruns (a run that needed one fails), and what the
processes of a failed live test wrote.

The live tests (``slow``) get one rerun (tests/conftest.py): a failure that repeats is a
fault, one that does not is a race or a deadline missed under load. Either way the test
did not pass: the run fails, and its end names every rerun with the first attempt's
error, the end of its traceback and the tail of its processes' logs, so a flake cannot
hide behind the rerun.
These hooks are imported into tests/conftest.py; under pytest-xdist the reports come to
the controlling process, which prints them.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

LOG_TAIL_LINES = 40
"""Lines of each child log shown when a slow test fails."""
CRASH_LINES = 30
"""Lines of a rerun's first error shown."""
TRACE_LINES = 60
"""Lines of the end of a rerun's first traceback shown (the sub-exceptions of a group)."""
CHILD_LOGS = "child logs"
"""The report section holding them."""


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo[None]) -> Iterator[None]:
    """When a ``slow`` test fails, add the tail of every log its processes wrote under
    its ``tmp_path`` (``logs/<service>.log`` of ``manus up``/``manus demo``, netns logs)
    to its report: shown with the failure, or with the rerun in the run's summary."""
    outcome = yield
    report: pytest.TestReport = outcome.get_result()  # type: ignore[attr-defined]
    if report.when != "call" or not report.failed or item.get_closest_marker("slow") is None:
        return
    tmp = getattr(item, "funcargs", {}).get("tmp_path")
    if tmp is None:
        return
    logs = sorted(Path(tmp).rglob("*.log"))
    text = [f"{len(logs)} child log(s) under {tmp}"]
    for log in logs:
        lines = log.read_text(errors="replace").splitlines()[-LOG_TAIL_LINES:]
        text.append(f"--- {log.relative_to(tmp)} (last {len(lines)} lines)")
        text += lines
    report.sections.append((CHILD_LOGS, "\n".join(text)))


def _reruns(config: pytest.Config) -> list[pytest.TestReport]:
    reporter = config.pluginmanager.get_plugin("terminalreporter")
    return list(reporter.stats.get("rerun", [])) if reporter is not None else []


@pytest.hookimpl(tryfirst=True)
def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    """A run that needed a rerun did not pass."""
    if _reruns(session.config) and exitstatus == pytest.ExitCode.OK:
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


def pytest_terminal_summary(
    terminalreporter: pytest.TerminalReporter, exitstatus: int, config: pytest.Config
) -> None:
    """The number of reruns, and for each the first attempt's error and child logs."""
    reruns = _reruns(config)
    if not reruns:
        terminalreporter.write_sep("=", "reruns: 0", green=True)
        return
    terminalreporter.write_sep(
        "=", f"reruns: {len(reruns)} (a run with a rerun fails: the test did not pass)", red=True
    )
    for report in reruns:
        crash = getattr(report.longrepr, "reprcrash", None)
        why = crash.message if crash is not None else str(report.longrepr)
        lines = why.splitlines() or [""]
        terminalreporter.write_line(f"RERUN {report.nodeid}: {lines[0]}")
        for line in lines[1:CRASH_LINES]:
            terminalreporter.write_line(f"    {line}")
        trace = str(report.longrepr).splitlines()[-TRACE_LINES:]
        terminalreporter.write_line(f"  the first attempt's traceback (last {len(trace)} lines):")
        for line in trace:
            terminalreporter.write_line(f"    | {line}")
        for name, text in report.sections:
            if name == CHILD_LOGS:
                terminalreporter.write_line(text)
