"""Running a command that starts a whole stack (``manus demo``, ``manus up``) from a test.

``subprocess.run(timeout=...)`` kills such a command when it overruns, and its services,
each in a session of its own, keep running beside the rest of the suite (a failed try of
``test_stack_up`` once left a whole stack running for 28 minutes). Here an overrun, or the
test stopped by its own timeout, gets Ctrl-C first: the command stops its services; a
kill comes only if it has not ended 60 s later.
"""

from __future__ import annotations

import signal
import subprocess
from collections.abc import Sequence
from pathlib import Path

STOP_WAIT_S = 60.0
"""How long a command has to stop its services after Ctrl-C before it is killed [s]."""


def run_stack_command(
    cmd: Sequence[str], timeout: float, cwd: Path, env: dict[str, str]
) -> subprocess.CompletedProcess[str]:
    """``cmd``'s exit status and output once it ends.

    Raises:
        AssertionError: it ran longer than ``timeout`` [s] (stopped with Ctrl-C), with
            what it printed.
    """
    proc = subprocess.Popen(
        list(cmd), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=cwd, env=env
    )
    try:
        try:
            out, err = proc.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            out, err = stop(proc)
            raise AssertionError(
                f"{' '.join(cmd)} still running after {timeout:g} s (stopped with Ctrl-C):\n"
                f"{out}\n{err}"
            ) from None
    finally:
        if proc.poll() is None:  # the test itself was stopped (pytest-timeout, Ctrl-C)
            stop(proc)
    return subprocess.CompletedProcess(list(cmd), proc.returncode, out, err)


def stop(proc: subprocess.Popen[str]) -> tuple[str, str]:
    """Ctrl-C, then a kill after :data:`STOP_WAIT_S`; what it printed."""
    proc.send_signal(signal.SIGINT)
    try:
        return proc.communicate(timeout=STOP_WAIT_S)
    except subprocess.TimeoutExpired:
        proc.kill()
        return proc.communicate()
