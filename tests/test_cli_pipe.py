"""A reader of ``manus``'s output that goes away early (``manus ... | head``) ends the
command quietly, whichever command was printing: no traceback, the SIGPIPE status.
(argparse's ``--help`` and usage messages ignore a failed write by themselves.)"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from manus_stack.cli import BROKEN_PIPE_EXIT

ROOT = Path(__file__).resolve().parent.parent


@pytest.mark.parametrize(
    "args",
    [
        ["kin", "ik", "207.846097", "105", "200", "0", "-60", "0"],
        ["kin", "urdf"],
        ["scene", "check"],
        ["export", str(ROOT / "tests" / "data" / "thesis_square.mcap"), "--info"],
    ],
    ids=lambda a: " ".join(a[:2]),
)
def test_a_closed_pipe_ends_the_command_without_a_traceback(args: list[str]) -> None:
    read_end, write_end = os.pipe()
    os.close(read_end)  # the reader is gone before the first byte: every write fails
    try:
        run = subprocess.run(
            [sys.executable, "-m", "manus_stack.cli", *args],
            stdout=write_end,
            stderr=subprocess.PIPE,
            text=True,
            timeout=60,
            cwd=ROOT,
        )
    finally:
        os.close(write_end)
    assert "Traceback" not in run.stderr and "BrokenPipeError" not in run.stderr, run.stderr
    assert run.returncode == BROKEN_PIPE_EXIT
