"""Benchmarks behind ``manus bench``: each module's ``run(quick)`` returns its figures.

Figures are printed as JSON, never asserted in unit tests (speed depends on the machine).
"""

from __future__ import annotations

BENCHES: dict[str, tuple[str, bool]] = {
    "kin": ("manus_stack.bench.kin", True),
    "plan": ("manus_stack.bench.plan", True),
    "bridge": ("manus_stack.bench.bridge", False),
    "track": ("manus_stack.bench.track", False),
    "follow": ("manus_stack.bench.follow", False),
    "sequencer": ("manus_stack.bench.sequencer", False),
    "replay": ("manus_stack.bench.replay", False),
    "guardian": ("manus_stack.bench.guardian", False),
    "fuzz": ("manus_stack.bench.fuzz", False),
    "collision": ("manus_stack.bench.collision", False),
    "validity": ("manus_stack.bench.validity", False),
    "jog": ("manus_stack.bench.jog", False),
    "view": ("manus_stack.bench.view", False),
    "flight": ("manus_stack.bench.flight", False),
    "chaos": ("manus_stack.bench.chaos", False),
    "objects": ("manus_stack.bench.objects", False),
    "reach": ("manus_stack.bench.reach", False),
    "panel": ("manus_stack.bench.panel", False),
    "pick": ("manus_stack.bench.pick", False),
    "drink": ("manus_stack.bench.drink", False),
}
"""Bench name -> (module, runs in a plain ``manus bench``). Long ones must be named."""
