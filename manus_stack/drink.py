"""The drink demo's parts: its setting, the truth's judge, its table and its plot.

The task is the panel's ``drink.toml`` (:data:`TASK_FILE`: fold out, pick the cup, bring
it level toward the mouth, follow the mouth to the standoff and hold, put the cup back
where it was, home, fold in), run by the sequencer's own steps. The setting
(:class:`DrinkSetting`, drawn from a seed): the default scene, the arm folded, one cup on
the table at a seeded place, the simulated camera with its noise, latency and dropouts,
the user's mouth swaying (:data:`SWAY_MM` at :data:`SWAY_HZ`) and tracked with noise.

:class:`DrinkJudge` takes the simulator's truth (``sim/truth``, :class:`SimTruth`) and the
task's events, and gives the figures (:class:`DrinkFigures`) from the truth alone, never
from what the stack says of itself: time per phase (the task's steps, from their events),
the smallest distance of the arm's bodies and of the cup to the person, contacts, the
cup's largest tilt and the placement error. Used live by ``manus demo drink`` and in
lock-step by ``manus bench drink`` (docs/drink.md).
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from manus.grasp_poses import tilt
from manus.orientation import ypr_to_matrix
from manus.scene import default_scene
from schemas.objects import ContactClass
from schemas.sequencing import TaskEvent, TaskEventKind
from schemas.state import SimTruth
from services.simulator.target_config import TargetConfig

TASK_FILE = Path(__file__).resolve().parent / "panel" / "tasks" / "drink.toml"
"""The drink task, the one the panel's Drink button runs."""

TABLE_TOP_M = 0.74
"""The default scene's table top [m]."""
CUP_RADIUS_M, CUP_LENGTH_M = 0.040, 0.100
"""The shipped cup [m]."""
AREA_M = ((0.86, 1.00), (-0.25, -0.05))
"""Where the cup is drawn from: x, y ranges on the table, chair frame [m] (the camera's
view of the table has a blind band at y -0.30..-0.40 m behind the user's right arm)."""
SWAY_MM = (0.0, 15.0, 5.0)
"""The mouth's sway, per chair axis [mm] (side to side, up and down)."""
SWAY_HZ = 0.25
TRACKER_NOISE_MM = 0.5
TRACKER_JITTER_MS = 5.0
MAX_TILT_DEG = 10.0
"""The cup's largest tilt the demo allows [deg] (issue 29)."""
PLACE_TOLERANCE_M = 0.010
"""A cup put back farther than this from where it stood is a failure [m]."""


@dataclass(frozen=True)
class DrinkSetting:
    """One seeded drink: where the cup stands, and the simulator's seed.

    Attributes:
        seed: the simulator's seed (noise, latencies, dropouts) and the draw's.
        cup_xy: the cup's centre on the table, chair frame [m].
    """

    seed: int
    cup_xy: tuple[float, float]

    @classmethod
    def drawn(cls, seed: int) -> DrinkSetting:
        """The setting of ``seed``."""
        rng = np.random.default_rng(seed)
        x, y = rng.uniform(*AREA_M[0]), rng.uniform(*AREA_M[1])
        return cls(seed, (float(x), float(y)))

    @property
    def cup_xyz(self) -> tuple[float, float, float]:
        """The cup's centre, standing on the table [m]."""
        return (*self.cup_xy, TABLE_TOP_M + CUP_LENGTH_M / 2)

    def target(self) -> TargetConfig:
        """The user's mouth: swaying, tracked with noise and jitter."""
        return TargetConfig(
            enabled=True,
            sway_mm=SWAY_MM,
            sway_hz=SWAY_HZ,
            noise_mm=TRACKER_NOISE_MM,
            jitter_ms=TRACKER_JITTER_MS,
        )

    def objects_file(self) -> dict[str, Any]:
        """The simulator's objects file (docs/objects.md): the cup alone."""
        x, y, z = (round(v * 1e3, 1) for v in self.cup_xyz)
        cup = {
            "id": "cup",
            "class": "cup",
            "shape": "cylinder",
            "radius_mm": CUP_RADIUS_M * 1e3,
            "length_mm": CUP_LENGTH_M * 1e3,
            "xyz_mm": [x, y, z],
        }
        return {"version": 1, "objects": [cup]}

    def write(self, directory: Path) -> tuple[Path, Path]:
        """The simulator's objects file and config file, written into ``directory``:
        ``manus sim --objects OBJECTS --config CONFIG``."""
        directory.mkdir(parents=True, exist_ok=True)
        objects = directory / "drink_objects.yaml"  # JSON is YAML
        objects.write_text(json.dumps(self.objects_file(), indent=1), encoding="utf-8")
        config = directory / "drink_sim.json"
        config.write_text(json.dumps(self.sim_config(), indent=1), encoding="utf-8")
        return objects, config

    def sim_config(self) -> dict[str, Any]:
        """The simulator's config file (its seed and the moving mouth)."""
        t = self.target()
        return {
            "seed": self.seed,
            "target": {
                "enabled": True,
                "sway_mm": list(t.sway_mm),
                "sway_hz": t.sway_hz,
                "noise_mm": t.noise_mm,
                "jitter_ms": t.jitter_ms,
            },
        }


@dataclass
class DrinkFigures:
    """What the truth showed of one drink (lengths [mm], angles [deg], times [s])."""

    seed: int
    ok: bool
    failure: str
    phases_s: dict[str, float]
    task_s: float
    arm_min_person_mm: float | None
    cup_min_person_mm: float | None
    person_clearance_mm: float
    contacts: int
    person_contacts: int
    contact: str
    """The last contact's pair, body/object ('': none)."""
    tilt_max_deg: float
    placement_error_mm: float | None

    def row(self) -> dict[str, Any]:
        """The figures as JSON values."""
        return dict(self.__dict__)


FINAL = (TaskEventKind.SUCCEEDED, TaskEventKind.FAILED, TaskEventKind.CANCELLED)
"""The events that end a task (a failure's names the step it failed in)."""


def _phase(event: TaskEvent) -> str:
    return f"{event.step + 1} {event.kind}"


@dataclass
class DrinkJudge:
    """Collects the truth and the task's events of one drink (see the module docstring).

    Args:
        setting: where the cup stood.
    """

    setting: DrinkSetting
    samples: list[tuple[float, float | None, float | None, float]] = field(default_factory=list)
    """(time [s], arm to person [m], held cup to person [m], cup's tilt [rad])."""
    starts: dict[str, float] = field(default_factory=dict)
    """Each phase's start (simulated time [s])."""
    started_s: float | None = None
    ended_s: float | None = None
    final: TaskEvent | None = None
    last: SimTruth | None = None
    _arm_min: float = math.inf
    _tilt_max: float = 0.0

    def on_truth(self, truth: SimTruth) -> None:
        """One of the simulator's truths (every tick, or every sample)."""
        self.last = truth
        cup = next((o for o in truth.objects if o.id == "cup"), None)
        lean = tilt(ypr_to_matrix(*cup.ypr)) if cup is not None else 0.0
        near = truth.held_min_person if cup is not None and cup.held else None
        self._tilt_max = max(self._tilt_max, lean)
        if truth.person_clearance is not None:
            self._arm_min = min(self._arm_min, truth.person_clearance)
        self.samples.append((truth.stamp_ns / 1e9, truth.person_clearance, near, lean))

    def on_event(self, event: TaskEvent) -> None:
        """One of the task's events."""
        t = event.stamp_ns / 1e9
        if event.event == TaskEventKind.ACCEPTED and self.started_s is None:
            self.started_s = t
        elif event.event == TaskEventKind.STEP_STARTED:
            self.starts.setdefault(_phase(event), t)
        elif event.event in FINAL:
            self.final, self.ended_s = event, t

    def figures(self) -> DrinkFigures:
        """The figures, from the truth (see the module docstring)."""
        truth = self.last
        clearance = default_scene().clearance["person"]
        names = list(self.starts)
        ends = [self.starts[n] for n in names[1:]] + [self.ended_s or 0.0]
        phases = {n: round(e - self.starts[n], 2) for n, e in zip(names, ends, strict=True)}
        cup = next((o for o in truth.objects if o.id == "cup"), None) if truth else None
        error = None
        if cup is not None:
            error = float(
                np.hypot(cup.xyz[0] - self.setting.cup_xy[0], cup.xyz[1] - self.setting.cup_xy[1])
            )
        cup_min = truth.held_min_person if truth is not None else None
        person = _person_contacts(truth) if truth is not None else 0
        fig = DrinkFigures(
            seed=self.setting.seed,
            ok=False,
            failure="",
            phases_s=phases,
            task_s=round((self.ended_s or 0.0) - (self.started_s or 0.0), 2),
            arm_min_person_mm=_mm(self._arm_min if math.isfinite(self._arm_min) else None),
            cup_min_person_mm=_mm(cup_min),
            person_clearance_mm=round(clearance * 1e3, 1),
            contacts=truth.contacts if truth is not None else 0,
            person_contacts=person,
            contact=truth.contact if truth is not None and truth.contacts else "",
            tilt_max_deg=round(math.degrees(self._tilt_max), 2),
            placement_error_mm=_mm(error),
        )
        fig.failure = self._failure(
            fig, cup is not None and not cup.held and cup.resting_on == "table"
        )
        fig.ok = not fig.failure
        return fig

    def _failure(self, fig: DrinkFigures, on_table: bool) -> str:
        final = self.final
        if final is None:
            return "the task did not end"
        if final.event != TaskEventKind.SUCCEEDED:
            return f"task {final.event}: {final.reason}"
        why = []
        if fig.contacts or fig.person_contacts:
            why.append(f"{fig.contacts} contact tick(s), {fig.person_contacts} with the person")
        c = fig.person_clearance_mm
        for what, d in (("the arm", fig.arm_min_person_mm), ("the cup", fig.cup_min_person_mm)):
            if d is not None and d < fig.person_clearance_mm:
                why.append(f"{what} came {d:.1f} mm from the person (clearance {c:g} mm)")
        if fig.tilt_max_deg > MAX_TILT_DEG:
            why.append(f"the cup tilted {fig.tilt_max_deg:.1f} deg (at most {MAX_TILT_DEG:g})")
        if not on_table:
            why.append("the cup is not back on the table")
        elif (
            fig.placement_error_mm is not None and fig.placement_error_mm > PLACE_TOLERANCE_M * 1e3
        ):
            why.append(f"the cup is back {fig.placement_error_mm:.1f} mm from where it stood")
        return "; ".join(why)


def _mm(v: float | None) -> float | None:
    return None if v is None else round(v * 1e3, 1)


def _person_contacts(truth: SimTruth) -> int:
    """Contacts of the arm or the held cup with a person body (the truth's)."""
    people = {o.name for o in default_scene().objects if o.cls == ContactClass.PERSON}
    held = sum(1 for c in truth.object_contacts if c.cls == ContactClass.PERSON)
    arm = 1 if truth.contact.split("/")[-1] in people else 0
    return held + arm


def render(fig: DrinkFigures) -> str:
    """The figures as text."""
    out = [f"drink (seed {fig.seed}), judged on the simulator's truth:"]
    out += [f"  {name:<18} {secs:7.2f} s" for name, secs in fig.phases_s.items()]
    out.append(f"  {'whole task':<18} {fig.task_s:7.2f} s")
    c = fig.person_clearance_mm
    out.append(
        f"  arm to the person  {_or(fig.arm_min_person_mm)} mm at its nearest (clearance {c:g} mm)"
    )
    out.append(
        f"  cup to the person  {_or(fig.cup_min_person_mm)} mm at its nearest (clearance {c:g} mm)"
    )
    last = f"; the last: {fig.contact}" if fig.contact else ""
    out.append(
        f"  contacts           {fig.contacts} (with the person: {fig.person_contacts}{last})"
    )
    out.append(
        f"  cup's tilt         {fig.tilt_max_deg:.2f} deg at most (allowed {MAX_TILT_DEG:g})"
    )
    out.append(
        f"  placement error    {_or(fig.placement_error_mm)} mm "
        f"(allowed {PLACE_TOLERANCE_M * 1e3:g})"
    )
    out.append("  result             " + ("succeeded" if fig.ok else f"FAILED: {fig.failure}"))
    return "\n".join(out)


def _or(v: float | None) -> str:
    return "-" if v is None else f"{v:.1f}"


def plot(judge: DrinkJudge, out: Path, title: str) -> Path:
    """The arm's and the cup's distance to the person, and the cup's tilt, over time, with
    the phases marked, as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    t0 = judge.samples[0][0] if judge.samples else 0.0
    t = [s[0] - t0 for s in judge.samples]
    fig, (ax_d, ax_t) = plt.subplots(2, 1, figsize=(11, 6.4), sharex=True)
    arm = [s[1] * 1e3 if s[1] is not None else math.nan for s in judge.samples]
    cup = [s[2] * 1e3 if s[2] is not None else math.nan for s in judge.samples]
    ax_d.plot(t, arm, color="tab:blue", label="arm's bodies to the person")
    ax_d.plot(t, cup, color="tab:orange", label="held cup to the person (nearest so far)")
    clearance = default_scene().clearance["person"] * 1e3
    ax_d.axhline(clearance, color="tab:red", linestyle="--", label=f"clearance {clearance:g} mm")
    ax_d.set_ylabel("distance [mm]")
    ax_d.set_ylim(0, 600)
    ax_d.legend(loc="upper right")
    ax_d.grid(True, alpha=0.3)
    ax_t.plot(t, [math.degrees(s[3]) for s in judge.samples], color="tab:green")
    ax_t.axhline(MAX_TILT_DEG, color="tab:red", linestyle="--")
    ax_t.set_ylabel("cup's tilt [deg]")
    ax_t.set_xlabel("simulated time [s]")
    ax_t.grid(True, alpha=0.3)
    for name, start in judge.starts.items():
        for ax in (ax_d, ax_t):
            ax.axvline(start - t0, color="grey", alpha=0.4, linewidth=0.8)
        ax_d.text(start - t0, 580, name, rotation=90, va="top", fontsize=7, color="grey")
    fig.suptitle(title)
    fig.tight_layout()
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    return out
