"""How the suite runs in parallel (pytest-xdist): the live tests in a few lanes at once,
the pure tests on the other workers.

The live tests (marked ``slow``) run real processes against 60 ms real-time cycles, but
they mostly wait: a whole stack uses a quarter of a core. Its processes on the arm's loop
raise their own priority to a real-time one (:mod:`manus.realtime`, the product's
default), so a CPU-bound process beside them (a pure test, another stack's start-up, a
CPU hog) no longer delays them, and :func:`live_lanes` live tests run at once, one per
lane worker (the first ones, ``gw0``...). A lane takes the live tests one unit at a
time: the tests of a module whose fixtures outlive a test (a module-scoped stack) form
one unit, so that the module's fixture is built once, on one lane; every other live test
is a unit of its own. The units marked ``slow(long=True)`` (the chaos soak) go first, then
the larger units, so that the lanes end together. The other workers take the pure tests
at a lower priority where the live ones cannot run real-time (:data:`PURE_NICE`), so the
test processes of the live lanes get the CPU first; once no live unit is left, the lanes
take pure tests too.

A run that names test files or ids runs in one process (parallel only costs start-up
there); ``-n N`` asks for workers anyway. The whole suite, ``python -m pytest`` from the
repository, gets :func:`workers` of them.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import pytest

from tests import live_priority

LIVE_IDS = "MANUS_TEST_LIVE_IDS"
"""Environment variable: the file where the workers write the live tests for the
scheduler (xdist sends the controlling process ids only, not markers)."""
LANES = "MANUS_TEST_LIVE_LANES"
"""Environment variable: how many live tests may run at once (default :data:`LIVE_LANES`;
1: one after the other)."""
LIVE_LANES = 3
"""Live tests at once by default: measured on the 2-core machine (docs/testing.md)."""
MAX_PURE = 8
"""Workers of pure tests at most (one per CPU)."""
PURE_NICE = 5
"""Niceness of the workers of pure tests where a live test cannot run real-time
(:mod:`tests.live_priority`): the lanes' test processes (niceness 0) get three times their
share of a contended core, yet a pure test keeps a quarter of a core when a CPU hog
(niceness 0) loads every core, so its own bounded waits still hold. Where they can, the
pure tests run at niceness 0: the live ones take a core first anyway, and a CPU-bound
property test (25 s alone) took more than pytest-timeout's 120 s at a quarter of a core
beside two hogs."""
_OWN_FILE = pytest.StashKey[str]()


def live_lanes(workers: int) -> int:
    """Lanes among ``workers`` workers: :data:`LANES` or :data:`LIVE_LANES`, leaving one
    worker for the pure tests (one worker: it runs everything)."""
    wanted = int(os.environ.get(LANES) or LIVE_LANES)
    return max(1, min(wanted, workers - 1))


def is_lane(worker_id: str, workers: int) -> bool:
    """``gw<N>`` is a live lane (the first :func:`live_lanes` workers)."""
    return worker_id.startswith("gw") and int(worker_id[2:]) < live_lanes(workers)


def pytest_configure(config: pytest.Config) -> None:
    """In the controlling process: a file for the live tests, which the workers it starts
    find in their environment. In a worker of pure tests: :data:`PURE_NICE`."""
    worker = getattr(config, "workerinput", None)
    if worker is not None and not is_lane(worker["workerid"], worker["workercount"]):
        os.nice(0 if live_priority.permitted() else PURE_NICE)
    if worker is None and LIVE_IDS not in os.environ:
        handle, path = tempfile.mkstemp(prefix="manus-live-tests-", suffix=".txt")
        os.close(handle)
        os.environ[LIVE_IDS] = path
        config.stash[_OWN_FILE] = path


def pytest_unconfigure(config: pytest.Config) -> None:
    """Remove the file this process made."""
    path = config.stash.get(_OWN_FILE, None)
    if path is not None:
        Path(path).unlink(missing_ok=True)
        os.environ.pop(LIVE_IDS, None)


def units(live: list[pytest.Item]) -> list[list[str]]:
    """The live tests in units (see the module docstring), in the order the lanes take
    them: ``slow(long=True)`` first, then by size, else in collection order."""
    groups: dict[str, list[pytest.Item]] = {}
    for item in live:
        info = getattr(item, "_fixtureinfo", None)  # a pytest.Function's fixtures
        shared = info is not None and any(
            fixture.scope != "function"
            for defs in info.name2fixturedefs.values()
            for fixture in defs
            if fixture.baseid  # the suite's own fixtures, not a plugin's session ones
        )
        module = getattr(item, "module", None)
        key = module.__name__ if shared and module is not None else item.nodeid
        groups.setdefault(key, []).append(item)
    ordered = sorted(groups.values(), key=lambda unit: (not any(map(_long, unit)), -len(unit)))
    return [[item.nodeid for item in unit] for unit in ordered]


def _long(item: pytest.Item) -> bool:
    mark = item.get_closest_marker("slow")
    return mark is not None and bool(mark.kwargs.get("long"))


def tell_live(config: pytest.Config, live: list[pytest.Item]) -> None:
    """In a worker, after collection: write the live tests' units, one test a line
    (``<unit>\\t<nodeid>``; every worker collects the same tests and writes the same file,
    before it reports its collection)."""
    path = os.environ.get(LIVE_IDS)
    if hasattr(config, "workerinput") and path:
        part = Path(f"{path}.{os.getpid()}")
        lines = [f"{n}\t{nodeid}\n" for n, unit in enumerate(units(live)) for nodeid in unit]
        part.write_text("".join(lines))
        part.replace(path)


def workers(config: pytest.Config) -> int:
    """Workers for ``-n auto``: the live lanes plus one per CPU (at most :data:`MAX_PURE`)
    for the whole suite, none (one process) when the command line names what to run.
    ``PYTEST_XDIST_AUTO_NUM_WORKERS`` overrides both."""
    forced = os.environ.get("PYTEST_XDIST_AUTO_NUM_WORKERS")
    if forced:
        return int(forced)
    if config.args_source != pytest.Config.ArgsSource.TESTPATHS:
        return 0
    pure = min(MAX_PURE, max(1, os.cpu_count() or 1))
    return pure + live_lanes(pure + int(os.environ.get(LANES) or LIVE_LANES))


def live_units() -> list[list[str]]:
    """The units the workers wrote, in the order to run (:func:`tell_live`)."""
    path = os.environ.get(LIVE_IDS)
    found: dict[str, list[str]] = {}
    for line in Path(path).read_text().splitlines() if path else []:
        unit, _, nodeid = line.partition("\t")
        found.setdefault(unit, []).append(nodeid)
    return list(found.values())


class LiveApartScheduling:
    """xdist scheduling with the live tests in lanes (see the module docstring).

    Implements ``xdist.scheduler.protocol.Scheduling``. A worker runs a test once it
    holds the next one (or is told to shut down), so each worker keeps one test queued.

    Args:
        config: the session's configuration.
        log: xdist's log producer.
    """

    def __init__(self, config: pytest.Config, log: Any) -> None:
        from xdist.workermanage import parse_tx_spec_config

        self.numnodes = len(parse_tx_spec_config(config))
        self.lanes = live_lanes(self.numnodes)
        self.log = log.livesched
        self.node2collection: dict[Any, list[str]] = {}
        self.node2pending: dict[Any, list[int]] = {}
        self.collection: list[str] | None = None
        self.units: list[list[int]] = []
        """Live units not started (collection indices, in order)."""
        self.unit_of: dict[Any, list[int]] = {}
        """Lane -> what is left of the unit it runs."""
        self.pure: list[int] = []
        """Pure tests not sent yet."""
        self.live_ids: set[str] = set()
        """Ids of the live tests."""

    # -- what xdist asks ---------------------------------------------------------------------

    @property
    def nodes(self) -> list[Any]:
        """The workers taking part."""
        return list(self.node2pending)

    @property
    def collection_is_completed(self) -> bool:
        """Every initial worker has sent its collection."""
        return len(self.node2collection) >= self.numnodes

    @property
    def tests_finished(self) -> bool:
        """Every test sent and run (a worker's last one runs at its shutdown)."""
        if not self.collection_is_completed or self._live_left() or self.pure:
            return False
        return all(len(p) < 2 for p in self.node2pending.values())

    @property
    def has_pending(self) -> bool:
        """Tests not sent, or sent and not run."""
        return bool(self._live_left() or self.pure or any(self.node2pending.values()))

    def add_node(self, node: Any) -> None:
        """A worker is up."""
        self.node2pending[node] = []

    def add_node_collection(self, node: Any, collection: Sequence[str]) -> None:
        """A worker's collection (they must all be the same)."""
        if self.collection is not None and list(collection) != self.collection:
            self.log(f"worker {node.gateway.id} collected other tests: not used")
            return
        self.node2collection[node] = list(collection)

    def schedule(self) -> None:
        """The first distribution (or, after a worker was replaced, a new round)."""
        if self.collection is None:
            collections = list(self.node2collection.values())
            if any(c != collections[0] for c in collections):
                self.log("the workers collected different tests: nothing runs")
                return
            self.collection = collections[0]
            where = {nodeid: index for index, nodeid in enumerate(self.collection)}
            for unit in live_units():
                indices = [where[nodeid] for nodeid in unit if nodeid in where]
                self.live_ids |= {self.collection[i] for i in indices}
                if indices:
                    self.units.append(indices)
            self.pure = [
                i for i, nodeid in enumerate(self.collection) if nodeid not in self.live_ids
            ]
        for node in self.nodes:
            self.check_schedule(node)

    def mark_test_complete(self, node: Any, item_index: int, duration: float = 0) -> None:
        """A worker finished a test."""
        self.node2pending[node].remove(item_index)
        self.check_schedule(node)

    def mark_test_pending(self, item: str) -> None:
        """Run ``item`` again (pytest-rerunfailures, after its worker crashed)."""
        assert self.collection is not None
        index = self.collection.index(item)
        if item in self.live_ids:
            self.units.insert(0, [index])
        else:
            self.pure.insert(0, index)
        for node in self.nodes:
            self.check_schedule(node)

    def remove_pending_tests_from_node(self, node: Any, indices: Sequence[int]) -> None:
        """Only for work stealing, which this scheduling does not do."""
        raise NotImplementedError

    def remove_node(self, node: Any) -> str | None:
        """A worker left: at its shutdown, or crashed (its queue goes back, the rest of its
        live unit as a unit; the test it was running is returned)."""
        pending = self.node2pending.pop(node)
        rest = self.unit_of.pop(node, [])
        if not pending:
            return None
        assert self.collection is not None
        crashed = self.collection[pending.pop(0)]
        live = [i for i in pending if self.collection[i] in self.live_ids]
        if live or rest:
            self.units.insert(0, live + rest)
        self.pure[:0] = [i for i in pending if self.collection[i] not in self.live_ids]
        for other in self.nodes:
            self.check_schedule(other)
        return crashed

    # -- the policy --------------------------------------------------------------------------

    def _live_left(self) -> bool:
        return bool(self.units or any(self.unit_of.values()))

    def _is_lane(self, node: Any) -> bool:
        lanes = [n for n in self.nodes if is_lane(n.gateway.id, self.numnodes)]
        if not lanes and self._live_left():  # every lane died: another worker takes over
            lanes = [n for n in self.nodes if not n.shutting_down][:1]
        return node in lanes

    def check_schedule(self, node: Any) -> None:
        """Give ``node`` work: the next test of its live unit (or a new unit) if it is a
        lane, else pure tests a few at a time; shut it down when nothing is left for it."""
        if node.shutting_down or self.collection is None:
            return
        pending = self.node2pending[node]
        if self._is_lane(node):
            while len(pending) < 2:  # the one it runs and the next
                if not self.unit_of.get(node):
                    if not self.units:
                        break
                    self.unit_of[node] = self.units.pop(0)
                self._send(node, self.unit_of[node], 1)
            if len(pending) >= 2 or self.unit_of.get(node):
                return
        if self.pure:
            if len(pending) < 2:
                share = max(2, len(self.pure) // (4 * len(self.node2pending)))
                self._send(node, self.pure, share - len(pending))
            return
        node.shutdown()  # runs what it holds, then leaves (the live tests left: on lanes)

    def _send(self, node: Any, queue: list[int], count: int) -> None:
        chunk = queue[: max(count, 0)]
        if chunk:
            del queue[: len(chunk)]
            self.node2pending[node].extend(chunk)
            node.send_runtest_some(chunk)
