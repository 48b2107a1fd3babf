"""The chaos soak as a bench: ``manus bench chaos --minutes M [--seed N]``.

The whole stack of ``manus up`` on the simulator (with the recorder) runs tasks back to
back while a seeded schedule injects one fault per task (:mod:`manus_stack.chaos`);
prints ``faults_injected``, ``tasks_run``, ``invariant_violations`` (each naming the
round, fault, time and what was violated), ``worst_stop_ms`` per fault kind,
``recorder_lost_messages`` and a line per round. Logs, recordings and ``chaos.json``
stay in ``runs/chaos-<time>/``. ``--quick``: one minute. A targeted soak: ``--faults
bridge_sigkill,bridge_sigstop --tasks fold,square`` (names of the tables of
:mod:`manus_stack.chaos.schedule`; default: every one).
"""

from __future__ import annotations

import sys
import time
from pathlib import Path
from typing import Any

from manus_stack.chaos.schedule import FAULTS, TASKS, select
from manus_stack.chaos.soak import run_soak

OPTIONS = ("minutes", "seed", "faults", "tasks")
"""Options of ``manus bench`` this bench takes."""


def run(
    quick: bool,
    minutes: float | None = None,
    seed: int | None = None,
    faults: str | None = None,
    tasks: str | None = None,
) -> dict[str, Any]:
    """Run the soak for ``minutes`` (default 10; 1 with ``quick``) with ``seed`` (0), of
    the fault kinds and tasks named (comma-separated; default: all)."""
    length = minutes if minutes is not None else (1.0 if quick else 10.0)
    kinds = select(faults or "", FAULTS, "fault kind(s)")
    chosen = select(tasks or "", TASKS, "task(s)")
    run_dir = Path("runs") / time.strftime("chaos-%Y%m%d-%H%M%S")
    seed = 0 if seed is None else seed
    return run_soak(run_dir.resolve(), length, seed, sys.stderr, kinds, chosen)
