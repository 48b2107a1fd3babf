"""Lock-step recordings of the thesis paths: the regression data kept in ``tests/data``.

:func:`record_thesis_run` runs simulator + bridge + controller cores in lock-step
(:class:`~manus_stack.controlled.ControlledArm`), plans the path with the planner core
through the ``planner/plan`` query as the live stack does (mirrored on
``trace/planner/plan/...``), submits it to the controller (``trace/controller/goal/...``),
runs until its result and a little after, and writes every message published, at its
simulated time, to MCAP (with the simulator's truth once per cycle, for plots).

Regenerate the files after a deliberate change of a core's behaviour::

    .venv/bin/python -m manus_stack.recordings            # writes tests/data/*.mcap

(the thesis square and circle in the default mode, and the square in the thesis mode)

then check the change in the plots (``manus plot tests/data/thesis_square.mcap``).
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from manus.viapoints import parse_viapoints
from manus_stack.controlled import ControlledArm
from schemas import endpoints as ep
from schemas.base import Message
from schemas.control import TrajectoryGoal
from schemas.planning import PlanReply, PlanRequest
from services.planner.core import PlannerCore
from services.planner.wiring import WIRING as PLANNER
from services.recorder.writer import RecordingWriter
from services.simulator.config import SimConfig

ROOT = Path(__file__).resolve().parents[1]
PATHS = ROOT / "paths"
DATA = ROOT / "tests" / "data"
RECORDINGS: dict[str, tuple[str, str]] = {
    "thesis_square": ("square", "default"),
    "thesis_circle": ("circle", "default"),
    "thesis_square_thesis_mode": ("square", "thesis"),
}
"""The files of ``tests/data``: name -> (thesis path, controller mode)."""
CYCLE_S = 0.06
AFTER_S = 0.5
"""Simulated time recorded after the goal's result [s]."""


@dataclass(frozen=True)
class RecordedRun:
    """One lock-step run written to a file.

    Attributes:
        output: the MCAP file.
        messages: messages written.
        status: the goal's result status.
        via_errors_mm: its via-point errors [mm].
        simulated_s: simulated time covered [s].
    """

    output: Path
    messages: int
    status: str
    via_errors_mm: list[float]
    simulated_s: float


def record_thesis_run(
    shape: str, output: str | Path, *, mode: str = "default", seed: int = 0
) -> RecordedRun:
    """Run ``paths/thesis_<shape>.txt`` in lock-step and record it to ``output``.

    Raises:
        RuntimeError: the planner or the controller refused, or no result came.
    """
    return record_thesis_runs([shape], output, mode=mode, seed=seed)


def record_thesis_runs(
    shapes: list[str], output: str | Path, *, mode: str = "default", seed: int = 0
) -> RecordedRun:
    """Run the thesis paths ``shapes`` one after the other (each planned from where the
    previous one left the arm) in one lock-step session and record it to ``output``.

    Returns:
        the run; ``status`` and ``via_errors_mm`` are those of the last goal.

    Raises:
        RuntimeError: the planner or the controller refused, or no result came.
    """
    arm = ControlledArm(SimConfig(start_pose="unfolded", seed=seed))
    planner = PlannerCore()

    def follow(suffix: str) -> Callable[[Message, int], list[tuple[str, Message]]]:
        """The planner's subscriptions (joint states, perception) in, its scene states and
        world updates out (the plans are asked below)."""
        return lambda msg, t_ns: list(PLANNER.feed(planner, suffix, msg, t_ns))

    def cycle() -> None:
        arm.ls.run_for(CYCLE_S)
        arm.ls.publish(ep.SIM_TRUTH, arm.ls.sim.truth())

    for inp in PLANNER.inputs:
        arm.ls.subscribe(inp.endpoint, follow(inp.endpoint))
    arm.start()
    result = None
    for i, shape in enumerate(shapes):
        name = f"paths/thesis_{shape}.txt"  # not the checkout's path: the same in any clone
        request = PlanRequest(path=parse_viapoints((PATHS.parent / name).read_text(), name))
        arm.ls.publish(ep.PLAN.trace("request"), request)
        reply: PlanReply = planner.plan(request)
        arm.ls.publish(ep.PLAN.trace("reply"), reply)
        if reply.trajectory is None:
            raise RuntimeError(f"thesis_{shape}: the planner refused: {reply.error}")
        goal_id = f"thesis_{shape}" if len(shapes) == 1 else f"thesis_{shape}_{i}"
        goal = TrajectoryGoal(goal_id=goal_id, trajectory=reply.trajectory, mode=mode)
        ack = arm.submit(goal)
        if not ack.accepted:
            raise RuntimeError(f"{goal.goal_id}: the controller refused: {ack.reason}")
        span = reply.trajectory.times[-1] + goal.goal_time_tolerance + 5
        limit = arm.ls.t_ns + round(span * 1e9)
        while not arm.results(goal.goal_id):
            if arm.ls.t_ns >= limit:
                raise RuntimeError(f"{goal.goal_id}: no result by {limit / 1e9:.1f} s")
            cycle()
        for _ in range(round(AFTER_S / CYCLE_S)):
            cycle()
        result = arm.results(goal.goal_id)[0]
    assert result is not None, "no shapes given"
    source = f"lockstep thesis_{'+'.join(shapes)} mode={mode} seed={seed}"
    with RecordingWriter(output, source=source, flush_interval_ns=10**9) as writer:
        for t_ns, suffix, msg in arm.ls.messages:
            writer.write(suffix, msg, t_ns)
    return RecordedRun(
        Path(output),
        len(arm.ls.messages),
        result.status,
        [e * 1e3 for e in result.via_errors],
        arm.ls.t_ns / 1e9,
    )


def main(argv: list[str] | None = None) -> int:
    """Regenerate the files of :data:`RECORDINGS` in ``tests/data`` (or ``--out``)."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=DATA, help="directory (default tests/data)")
    parser.add_argument(
        "names", nargs="*", metavar="NAME", help=f"{', '.join(RECORDINGS)} (default: all)"
    )
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    for name in args.names or RECORDINGS:
        if name not in RECORDINGS:
            parser.error(f"recording {name!r} is not one of {list(RECORDINGS)}")
        shape, mode = RECORDINGS[name]
        run = record_thesis_run(shape, args.out / f"{name}.mcap", mode=mode)
        size = run.output.stat().st_size
        sys.stdout.write(
            f"{run.output}: {run.messages} messages, {size / 1024:.0f} KiB, "
            f"{run.simulated_s:.1f} s simulated, {run.status}, via mean "
            f"{sum(run.via_errors_mm[1:]) / max(1, len(run.via_errors_mm) - 1):.2f} mm "
            "(start pose not counted)\n"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
