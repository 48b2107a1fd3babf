"""The fast validity check (:mod:`manus.validity`) against the exact one (Coal), in one run.

- ``per_configuration``: 2,000 seeded random configurations (uniform within the joint
  limits) of the default scene, one call each, timed one by one: Coal's
  :meth:`CollisionModel.tightest`, ``margins`` and ``clearance``, and the fast
  ``is_valid`` and ``margins``; batched (``is_valid_batch``, ``margins_batch``) in
  batches of 100, per configuration. ``speedup``: ``tightest`` p50 over the fast p50.
- ``conservative``: 100,000 seeded configurations (half uniform within the limits, half
  about the unfolded pose, where the arm works: near the user, the chair and the table),
  the fast verdict against Coal's ``clearance``. ``false_free`` (valid for the fast check,
  a clearance broken for Coal) must be 0; ``over_conservative`` counts the configurations
  Coal finds clear that the fast check refuses, and ``gap_mm`` how far the fast margin is
  below Coal's where Coal finds them clear.
- ``motion``: :meth:`ValidityChecker.motion_valid` between seeded pairs of valid
  configurations up to 0.5 rad apart per joint: time per motion, how many are proven.
- ``held``: the same with a cup held across the gripper's jaws (radius 40, length 100
  mm; :class:`manus.held.HeldBody`): building the model and checker that carry it (what
  the guard, the planner and the fold check pay at an attach), the one-call and batched
  costs against Coal's ``tightest`` with it, and the conservativeness on a tenth as many
  configurations.
- ``first_call``: building the first checker in a fresh process with an empty numba
  cache (compiling every kernel) and again with the cache filled (what a service pays
  at start-up).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from typing import Any

import numpy as np

from manus.collision import CollisionModel
from manus.config import DEFAULT_ARM, UNFOLDED_Q_DEG
from manus.held import HeldBody
from manus.scene import default_scene
from manus.validity import MOTION_FLOOR_M, SLACK_M, ValidityChecker

TARGET = "fast p50 <= 3 us batched and >= 10x tightest; 0 false free in 100,000"


def seeded(n: int, seed: int, near: float = 0.5) -> np.ndarray:
    """``n`` configurations [rad]: the first ``(1 - near) n`` uniform within the joint
    limits, the rest normal about the unfolded pose (0.6 rad standard deviation)."""
    rng = np.random.default_rng(seed)
    wide = round(n * (1.0 - near))
    lo, hi = DEFAULT_ARM.lower_array, DEFAULT_ARM.upper_array
    around = np.radians(UNFOLDED_Q_DEG) + rng.normal(0.0, 0.6, (n - wide, 6))
    return np.vstack((rng.uniform(lo, hi, (wide, 6)), around))


def _us(samples: list[float] | np.ndarray) -> dict[str, float]:
    a = np.asarray(samples) * 1e6
    return {
        "p50_us": round(float(np.percentile(a, 50)), 2),
        "p99_us": round(float(np.percentile(a, 99)), 2),
    }


def _one_by_one(fn: Any, Q: np.ndarray) -> list[float]:
    out = []
    for q in Q:
        started = time.perf_counter()
        fn(q)
        out.append(time.perf_counter() - started)
    return out


def _batched(fn: Any, Q: np.ndarray, size: int = 100) -> list[float]:
    out = []
    for k in range(0, len(Q), size):
        chunk = Q[k : k + size]
        started = time.perf_counter()
        fn(chunk)
        out.append((time.perf_counter() - started) / len(chunk))
    return out


def _per_configuration(model: CollisionModel, fast: ValidityChecker) -> dict[str, Any]:
    Q = seeded(2000, seed=2026, near=0.0)
    for q in Q[:50]:  # warm up every path
        model.clearance(q)
        fast.margins(q)
    coal = {
        name: _us(_one_by_one(fn, Q))
        for name, fn in (
            ("tightest", model.tightest),
            ("margins", model.margins),
            ("clearance", model.clearance),
        )
    }
    ours = {
        "is_valid": _us(_one_by_one(fast.is_valid, Q)),
        "margins": _us(_one_by_one(fast.margins, Q)),
        "is_valid_batch": _us(_batched(fast.is_valid_batch, Q)),
        "margins_batch": _us(_batched(fast.margins_batch, Q)),
    }
    tightest = coal["tightest"]["p50_us"]
    return {
        "configurations": len(Q),
        "valid_fraction": round(float(fast.is_valid_batch(Q).mean()), 3),
        "coal": coal,
        "fast": ours,
        "speedup_batched": round(tightest / ours["is_valid_batch"]["p50_us"], 1),
        "speedup_single": round(tightest / ours["is_valid"]["p50_us"], 1),
        "speedup_margins_batched": round(tightest / ours["margins_batch"]["p50_us"], 1),
    }


def _conservative(model: CollisionModel, fast: ValidityChecker, n: int) -> dict[str, Any]:
    Q = seeded(n, seed=26)
    valid = fast.is_valid_batch(Q)
    bound = fast.margins_batch(Q).tight
    exact = np.array([model.clearance(q).margin for q in Q])
    clear = exact >= 0.0
    gap = (exact - bound)[clear] * 1e3
    over = clear & ~valid
    return {
        "configurations": n,
        "coal_clear": int(clear.sum()),
        "false_free": int((valid & ~clear).sum()),
        "bound_above_coal": int((bound > exact)[clear].sum()),
        "over_conservative": int(over.sum()),
        "over_conservative_fraction_of_clear": round(float(over.sum() / max(1, clear.sum())), 4),
        "over_conservative_coal_margin_mm": {
            "p50": round(float(np.percentile(exact[over] * 1e3, 50)), 2) if over.any() else 0.0,
            "max": round(float(exact[over].max() * 1e3), 2) if over.any() else 0.0,
        },
        "gap_mm": {
            "p50": round(float(np.percentile(gap, 50)), 3),
            "p90": round(float(np.percentile(gap, 90)), 2),
            "p99": round(float(np.percentile(gap, 99)), 2),
            "max": round(float(gap.max()), 2),
        },
        "slack_mm": SLACK_M * 1e3,
    }


def _motion(fast: ValidityChecker, n: int) -> dict[str, Any]:
    rng = np.random.default_rng(7)
    Q = seeded(4 * n, seed=8)
    starts = Q[fast.is_valid_batch(Q)][:n]
    ends = starts + rng.uniform(-0.5, 0.5, starts.shape)
    times, proven = [], 0
    for a, b in zip(starts, ends, strict=True):
        started = time.perf_counter()
        found = fast.motion_valid(a, b)
        times.append(time.perf_counter() - started)
        proven += found.ok
    return {
        "motions": len(starts),
        "proven": proven,
        **_us(times),
        "floor_mm": MOTION_FLOOR_M * 1e3,
    }


CUP = HeldBody("cup", "cup", "cylinder", (0.04, 0.1), (0.0, 0.0, 0.0), (0.0, 0.0, np.pi / 2))
"""A cup held across the jaws (its axis along the gripper frame's y)."""


def _held(model: CollisionModel, n: int) -> dict[str, Any]:
    builds = []
    for _ in range(20):
        started = time.perf_counter()
        held = model.holding([CUP])
        fast = ValidityChecker(held)
        builds.append(time.perf_counter() - started)
    Q = seeded(2000, seed=2026, near=0.0)
    tightest = _us(_one_by_one(held.tightest, Q))
    batched = _us(_batched(fast.is_valid_batch, Q))
    return {
        "held": CUP.name,
        "build_ms": {
            "p50": round(float(np.percentile(builds, 50)) * 1e3, 2),
            "max": round(max(builds) * 1e3, 2),
        },
        "coal_tightest": tightest,
        "fast_is_valid": _us(_one_by_one(fast.is_valid, Q)),
        "fast_margins": _us(_one_by_one(fast.margins, Q)),
        "fast_is_valid_batch": batched,
        "speedup_batched": round(tightest["p50_us"] / batched["p50_us"], 1),
        "conservative": _conservative(held, fast, n),
    }


_BUILD = (
    "import time; t = time.perf_counter(); "
    "from manus.collision import CollisionModel; from manus.config import DEFAULT_ARM; "
    "from manus.scene import default_scene; from manus.validity import ValidityChecker; "
    "m = CollisionModel(default_scene(), DEFAULT_ARM); s = time.perf_counter(); "
    "ValidityChecker(m); print(time.perf_counter() - s)"
)


def _first_call() -> dict[str, float]:
    """Seconds to build the first checker in a fresh process: numba cache empty, then
    filled (a separate cache directory: the checkout's stays as it is)."""
    with tempfile.TemporaryDirectory(prefix="manus-numba-") as cache:
        env = {**os.environ, "NUMBA_CACHE_DIR": cache}

        def build() -> float:
            out = subprocess.run(
                [sys.executable, "-c", _BUILD], env=env, capture_output=True, text=True, check=True
            )
            return round(float(out.stdout.strip()), 3)

        return {"compile_s": build(), "from_cache_s": build()}


def run(quick: bool = False) -> dict[str, Any]:
    """The figures above (``quick``: 10,000 configurations for the conservativeness)."""
    model = CollisionModel(default_scene(), DEFAULT_ARM)
    fast = ValidityChecker(model)
    return {
        "scene": str(default_scene().source),
        "bodies": fast.bodies,
        "per_configuration": _per_configuration(model, fast),
        "conservative": _conservative(model, fast, 10_000 if quick else 100_000),
        "motion": _motion(fast, 200 if quick else 1000),
        "held": _held(model, 1000 if quick else 10_000),
        "first_call": _first_call(),
        "target": TARGET,
    }
