"""The thesis's step response again: joint 2's response to each of the ten speed commands.

For each speed n = 1..10 counts (0.1 deg per 20 ms each, 5..50 deg/s) a fresh simulator
starts with the arm fully stretched and horizontal (DH q = (0, 0, 90, 0, 0, 0)); a
scripted PC waits for "absolute angles measured", enters joint mode with a zero 0x374,
then sends the constant joint-2 command n at every sync. t = 0 is the tick at which the
command becomes active (as in the thesis: the joint stays still for 60 ms, the first-motion
delay, then reaches its speed through the ~60 ms transient; docs/protocol.md, Thesis step
response). Joint 2's motor angle change
is sampled as the encoder reports it (0x350, once per 60 ms) and as the truth (every 5 ms).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from manus.protocol import ZERO_JOINT_MOVE, FrameId, MoveCommand, move_frame
from services.simulator.config import SimConfig
from services.simulator.core import MS, SimCore
from services.simulator.scripted import ScriptedPc

STRETCHED_Q_DEG = (0.0, 0.0, 90.0, 0.0, 0.0, 0.0)
"""Arm horizontal and fully stretched, as in the thesis test [deg]."""
SPEEDS = tuple(range(1, 11))
DURATION_MS = 420
SAMPLE_MS = 5


@dataclass(frozen=True)
class StepRun:
    """One speed's response.

    Attributes:
        counts: the commanded increment [0.1 deg per 20 ms].
        encoder_t_ms: times of the encoder samples since the step [ms], shape (k,).
        encoder_deg: reported joint 2 motor angle change [deg], shape (k,).
        truth_t_ms: times of the truth samples [ms], shape (m,).
        truth_deg: true joint 2 angle change, in the motor's sense [deg], shape (m,).
    """

    counts: int
    encoder_t_ms: np.ndarray
    encoder_deg: np.ndarray
    truth_t_ms: np.ndarray
    truth_deg: np.ndarray


def step_run(counts: int, config: SimConfig | None = None) -> StepRun:
    """Simulate one step of ``counts`` on joint 2 (lock-step, a few ms of CPU)."""
    base = config or SimConfig()
    core = SimCore(base.with_overrides(start_pose=STRETCHED_Q_DEG))
    pc = ScriptedPc(core)
    pc.wait_ready()
    pc.run_cycles(2, move_frame(ZERO_JOINT_MOVE))
    step = move_frame(MoveCommand(FrameId.JOINT, 0, (0, counts, 0, 0, 0, 0), 0))
    # Answer the next sync with the step: it becomes active 20 ms after the window.
    pc.run_cycles(1, step)
    sync = max(f.t_ns for f in pc.frames if f.id == FrameId.SYNC)
    t_step = sync + 20 * MS
    pc.run(t_step, step)
    e0 = float(core.state_at(t_step).output_deg[1])
    first = len(pc.cycles) - 1
    truth_t, truth_deg = [], []
    for t_ms in range(0, DURATION_MS + 1, SAMPLE_MS):
        t = t_step + t_ms * MS
        pc.run(t, step)
        truth_t.append(float(t_ms))
        truth_deg.append(float(core.state_at(t).output_deg[1]) - e0)
    cycles = pc.cycles[first:]
    enc0 = cycles[0].fields[1]
    enc_t = np.array([(c.t_ns - t_step) / MS for c in cycles])
    enc = np.array([(c.fields[1] - enc0) * 0.1 for c in cycles])
    return StepRun(counts, enc_t, enc, np.array(truth_t), np.array(truth_deg))


def plot_step_response(path: str | Path, config: SimConfig | None = None) -> Path:
    """Write the figure (PNG) for all ten speeds; returns the path written."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    runs = [step_run(n, config) for n in SPEEDS]
    fig, ax = plt.subplots(figsize=(8, 6), dpi=120)
    cmap = plt.get_cmap("viridis")
    for i, run in enumerate(runs):
        colour = cmap(i / (len(runs) - 1))
        ax.plot(
            run.truth_t_ms,
            run.truth_deg,
            color=colour,
            lw=1.2,
            label=f"{run.counts} ({run.counts * 5} deg/s)",
        )
        ax.step(
            run.encoder_t_ms,
            run.encoder_deg,
            where="post",
            color=colour,
            lw=0.8,
            ls="--",
            alpha=0.8,
        )
        ax.plot(run.encoder_t_ms, run.encoder_deg, "o", color=colour, ms=3)
    ax.axvspan(0, 60, color="0.9", zorder=0)
    ax.set_xlim(0, DURATION_MS)
    ax.set_xlabel("time since the step [ms]")
    ax.set_ylabel("joint 2 angle change [deg]")
    ax.set_title(
        "Step response of joint 2 (simulated; cf. the thesis's figure)\n"
        "solid: true angle; dots and dashed steps: encoder, every 60 ms"
    )
    ax.grid(True, alpha=0.3)
    ax.legend(title="command [counts]", fontsize=8, loc="upper left")
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    plt.close(fig)
    return out
