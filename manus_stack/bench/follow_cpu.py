"""The controller core's CPU per cycle while following (``manus bench follow``,
``cpu_ms_per_cycle``): :class:`Timed` wraps a lock-step arm's core for one run; the
module keeps every run's times until :func:`clear`, :func:`figures` sums them up.
"""

from __future__ import annotations

import gc
import time
from typing import Any

import numpy as np

from manus.process import freeze_startup_heap
from manus_stack.follow_lockstep import FollowArm
from services.controller.follow_source import FollowSource

CPU: list[float] = []
"""Per joint state while following, every run so far: the core's CPU time [s]."""
COLLECTED: list[float] = []
"""Per entry of :data:`CPU`, its part in garbage collections [s]."""
ASKED: list[float] = []
"""Per query to the core (a goal's), its CPU time [s]."""


class Timed:
    """The controller core's CPU time per joint state, the target frames taken since the
    last one included (wraps the core's entry points), and per query (a goal's
    admission: the guard prepares its checks there,
    :meth:`services.controller.run_guard.RunGuard.prepare`).

    From here to :meth:`done` the start-up heap is frozen, as the controller's process
    freezes its own once started (:func:`manus.process.freeze_startup_heap`): else a
    full collection walks every object of this lock-step process (simulator, bridge,
    the earlier runs: 50-130 ms) in whichever cycle it falls. The collections of what is
    made meanwhile stay in the figures, the simulator's and the probe's objects too
    (most of what is made here: a cycle's collections are timed apart, ``collected``).
    """

    def __init__(self, arm: FollowArm) -> None:
        self.spent: list[float] = []
        self.collected: list[float] = []
        """Per joint state, the part of :attr:`spent` in garbage collections [s]."""
        self.asked: list[float] = []
        self._carry = self._carry_gc = 0.0
        self._inside, self._gc_from, self._gc_ns = False, 0, 0
        core = arm.core
        on_js, take, ask = core.on_joint_state, core.take, core.ask
        freeze_startup_heap()
        gc.callbacks.append(self._collection)

        def timed_js(js: Any) -> Any:
            self._inside, gc_ns = True, self._gc_ns
            t = time.thread_time_ns()
            out = on_js(js)
            spent = (time.thread_time_ns() - t) / 1e9
            self._inside = False
            if core.source(FollowSource).goal is not None:
                self.spent.append(self._carry + spent)
                self.collected.append(self._carry_gc + (self._gc_ns - gc_ns) / 1e9)
            self._carry = self._carry_gc = 0.0
            return out

        def timed_take(kind: Any, handle: Any, msg: Any) -> Any:
            self._inside, gc_ns = True, self._gc_ns
            t = time.thread_time_ns()
            out = take(kind, handle, msg)
            self._carry += (time.thread_time_ns() - t) / 1e9
            self._inside = False
            self._carry_gc += (self._gc_ns - gc_ns) / 1e9
            return out

        def timed_ask(*args: Any) -> Any:
            t = time.thread_time_ns()
            out = ask(*args)
            self.asked.append((time.thread_time_ns() - t) / 1e9)
            return out

        core.on_joint_state = timed_js  # type: ignore[method-assign]
        core.take = timed_take  # type: ignore[method-assign]
        core.ask = timed_ask  # type: ignore[method-assign, assignment]

    def _collection(self, phase: str, info: dict[str, int]) -> None:
        """A garbage collection starts or stops (``gc.callbacks``)."""
        if phase == "start":
            self._gc_from = time.thread_time_ns()
        elif self._inside:
            self._gc_ns += time.thread_time_ns() - self._gc_from

    def done(self) -> list[float]:
        """The times per joint state [s]; the heap unfrozen, the queries' and the
        collections' times kept."""
        gc.unfreeze()
        gc.callbacks.remove(self._collection)
        ASKED.extend(self.asked)
        COLLECTED.extend(self.collected)
        CPU.extend(self.spent)
        return self.spent


def clear() -> None:
    """Forget every run's times."""
    CPU.clear()
    COLLECTED.clear()
    ASKED.clear()


def figures() -> dict[str, Any]:
    """The figures of every run so far [ms] (module docstring of :mod:`.follow`)."""
    a = np.asarray(CPU) * 1e3
    less = a - np.asarray(COLLECTED) * 1e3
    return {
        "p50": round(float(np.median(a)), 3),
        "p99": round(float(np.percentile(a, 99)), 3),
        "max": round(float(a.max()), 3),
        "n": len(CPU),
        "goal_query_max": round(max(ASKED) * 1e3, 3),
        "cycles_with_a_collection": int(np.count_nonzero(COLLECTED)),
        "p99_less_collections": round(float(np.percentile(less, 99)), 3),
    }
