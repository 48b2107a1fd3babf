"""How the suite runs in parallel (pytest-xdist): the live tests in two lanes, the pure
tests on the other workers.

The live tests (marked ``slow``) run real processes against 60 ms real-time cycles. Two
lanes (:data:`LIVE_WORKERS`) run them one unit after another (:func:`units`) from the
start of the session, beside the workers of pure tests (one per CPU but one:
:func:`workers`). A live test's process and the services it starts run at a real-time
priority where permitted (:mod:`tests.live_priority`, :mod:`manus.realtime`), else the
pure tests run at a lower one (:data:`PURE_NICE`): either way a live test's processes
take a core at once when they wake. The units come longest first, so both lanes end on
short ones; a lane with no live unit left takes pure tests.

Why so: the live units hold about 500 s of wall time between them (a stack runs in real
time, mostly waiting), the pure tests about 200 s of CPU. With the second lane waiting
until every pure test was given out (two workers of them), it started at about 110 s and
the run took 317 s on 2 cores; with both lanes from the start and one worker of pure
tests, the three end together, about 260 s.

A run that names test files or ids runs in one process (parallel only costs start-up
there); ``-n N`` asks for workers anyway (with two workers, the second lane takes the
pure tests first). The whole suite, ``python -m pytest`` from the repository, gets
:func:`workers` of them.
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
"""Environment variable: the file where the workers write the ids of the live tests for
the scheduler (xdist sends the controlling process ids only, not markers)."""

MAX_WORKERS = 8
LIVE_WORKERS = ("gw0", "gw1")
"""The workers of the two live lanes, both from the start (the second after the pure tests
when no other worker takes them; another worker takes a lane only if its own died)."""
PURE_NICE = 5
"""Niceness of the workers of pure tests where a live test cannot run real-time
(:mod:`tests.live_priority`): a live test's processes (niceness 0) get three times their
share of a contended core, yet a pure test keeps a quarter of a core when a CPU hog
(niceness 0) loads every core, so its own bounded waits still hold. Where they can, the
pure tests run at niceness 0: the live ones take a core first anyway."""
_OWN_FILE = pytest.StashKey[str]()


def pytest_configure(config: pytest.Config) -> None:
    """In the controlling process: a file for the live tests' ids, which the workers it
    starts find in their environment. In a worker of pure tests: :data:`PURE_NICE` where
    a live test cannot run real-time."""
    worker = getattr(config, "workerinput", None)
    if worker is not None and worker.get("workerid") not in LIVE_WORKERS:
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
    """The live tests in units, in the order the lanes take them: the tests of a module
    whose fixtures outlive a test (the panel's stack and browser) form one unit, built
    once on one lane; every other live test is a unit of its own. Units marked
    ``slow(long=True)`` come first, then the larger ones, so that the lanes end on short
    units, together."""
    groups: dict[str, list[pytest.Item]] = {}
    for item in live:
        info = getattr(item, "_fixtureinfo", None)  # a pytest.Function's fixtures
        shared = info is not None and any(
            fixture.scope != "function"
            for defs in info.name2fixturedefs.values()
            for fixture in defs
            if fixture.baseid  # the suite's own fixtures, not a plugin's session ones
        )
        key = item.nodeid.split("::")[0] if shared else item.nodeid
        groups.setdefault(key, []).append(item)
    ordered = sorted(groups.values(), key=lambda unit: (not any(map(_long, unit)), -len(unit)))
    return [[item.nodeid for item in unit] for unit in ordered]


def _long(item: pytest.Item) -> bool:
    mark = item.get_closest_marker("slow")
    return mark is not None and bool(mark.kwargs.get("long"))


def tell_live(config: pytest.Config, live: list[pytest.Item]) -> None:
    """In a worker, after collection: write the live tests' units for the scheduler, one
    test a line (``<unit>\\t<nodeid>``; every worker collects the same tests and writes the
    same file, before it reports its collection)."""
    path = os.environ.get(LIVE_IDS)
    if hasattr(config, "workerinput") and path:
        part = Path(f"{path}.{os.getpid()}")
        lines = [f"{n}\t{nodeid}\n" for n, unit in enumerate(units(live)) for nodeid in unit]
        part.write_text("".join(lines))
        part.replace(path)


def workers(config: pytest.Config) -> int:
    """Workers for ``-n auto``: the two live lanes and a worker of pure tests for every CPU
    but one, at least one (at most :data:`MAX_WORKERS` in all; the two lanes' stacks take
    about a core between them: with three workers of pure tests beside one lane on 2
    cores, the live tests failed: a bridge resync, the soak's planner cut off) for the
    whole suite, none (one process) when the command line names what to run.
    ``PYTEST_XDIST_AUTO_NUM_WORKERS`` overrides both."""
    forced = os.environ.get("PYTEST_XDIST_AUTO_NUM_WORKERS")
    if forced:
        return int(forced)
    if config.args_source != pytest.Config.ArgsSource.TESTPATHS:
        return 0
    return min(MAX_WORKERS, len(LIVE_WORKERS) + max(1, (os.cpu_count() or 1) - 1))


def live_units() -> list[list[str]]:
    """The units the workers wrote, in order (:func:`tell_live`)."""
    path = os.environ.get(LIVE_IDS)
    found: dict[str, list[str]] = {}
    for line in Path(path).read_text().splitlines() if path else []:
        unit, nodeid = line.split("\t", 1)
        found.setdefault(unit, []).append(nodeid)
    return list(found.values())


class LiveApartScheduling:
    """xdist scheduling with the live tests apart (see the module docstring).

    Implements ``xdist.scheduler.protocol.Scheduling``. A worker runs a test once it
    holds the next one (or is told to shut down), so each worker keeps one test queued.

    Args:
        config: the session's configuration.
        log: xdist's log producer.
    """

    def __init__(self, config: pytest.Config, log: Any) -> None:
        from xdist.workermanage import parse_tx_spec_config

        self.numnodes = len(parse_tx_spec_config(config))
        self.log = log.livesched
        self.node2collection: dict[Any, list[str]] = {}
        self.node2pending: dict[Any, list[int]] = {}
        self.collection: list[str] | None = None
        self.live: list[list[int]] = []
        """Live units not sent yet: each the collection indices of its tests, in order."""
        self.pure: list[int] = []
        """Pure tests not sent yet."""
        self.lanes: list[Any] = [None] * len(LIVE_WORKERS)
        """The worker of each live lane (None: not chosen, or it died)."""
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
        if not self.collection_is_completed or self.live or self.pure:
            return False
        return all(len(p) < 2 for p in self.node2pending.values())

    @property
    def has_pending(self) -> bool:
        """Tests not sent, or sent and not run."""
        return bool(self.live or self.pure or any(self.node2pending.values()))

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
            units = [[where[n] for n in unit if n in where] for unit in live_units()]
            self.live = [unit for unit in units if unit]
            self.live_ids = {self.collection[i] for unit in self.live for i in unit}
            self.pure = [i for i, n in enumerate(self.collection) if n not in self.live_ids]
        for node in self.nodes:
            self.check_schedule(node)

    def mark_test_complete(self, node: Any, item_index: int, duration: float = 0) -> None:
        """A worker finished a test."""
        self.node2pending[node].remove(item_index)
        self.check_schedule(node)

    def mark_test_pending(self, item: str) -> None:
        """Run ``item`` again (pytest-rerunfailures, after its worker crashed)."""
        assert self.collection is not None
        self._put_back([self.collection.index(item)])
        for node in self.nodes:
            self.check_schedule(node)

    def remove_pending_tests_from_node(self, node: Any, indices: Sequence[int]) -> None:
        """Only for work stealing, which this scheduling does not do."""
        raise NotImplementedError

    def remove_node(self, node: Any) -> str | None:
        """A worker left: at its shutdown, or crashed (its queue goes back; the test it
        was running is returned)."""
        pending = self.node2pending.pop(node)
        self.lanes = [None if lane is node else lane for lane in self.lanes]
        if not pending:
            return None
        assert self.collection is not None
        crashed = self.collection[pending.pop(0)]
        self._put_back(pending)
        for other in self.nodes:
            self.check_schedule(other)
        return crashed

    # -- the policy --------------------------------------------------------------------------

    def check_schedule(self, node: Any) -> None:
        """Give ``node`` work: the next live unit if it holds a lane that may run now,
        else pure tests, a few at a time; when nothing is left to give, every worker runs
        what it holds and leaves."""
        if node.shutting_down or self.collection is None:
            return
        self._choose_lanes()
        pending = self.node2pending[node]
        lane = self.lanes.index(node) if node in self.lanes else None
        pure_workers = [n for n in self.nodes if n not in self.lanes and not n.shutting_down]
        if lane is not None and (lane == 0 or pure_workers or not self.pure):
            while self.live and len(pending) < 2:  # a worker runs a test once it holds the next
                self._send(node, self.live.pop(0))
        if len(pending) >= 2:
            return
        if self.pure and (lane is None or not pure_workers or not self.live):
            count = max(2, len(self.pure) // (4 * len(self.node2pending))) - len(pending)
            chunk, self.pure = self.pure[:count], self.pure[count:]
            self._send(node, chunk)
            if not self.pure and self.lanes[-1] not in (None, node):
                self.check_schedule(self.lanes[-1])  # the second lane's turn
        if not self.live and not self.pure:
            for each in self.nodes:  # each runs what it holds, then leaves
                if not each.shutting_down:
                    each.shutdown()

    def _choose_lanes(self) -> None:
        """The worker of each lane: its own one (:data:`LIVE_WORKERS`), else any other
        that holds no lane (its own died)."""
        if not self.live:
            return
        for i, name in enumerate(LIVE_WORKERS):
            if self.lanes[i] is not None:
                continue
            free = [n for n in self.nodes if n not in self.lanes and not n.shutting_down]
            named = [n for n in free if n.gateway.id == name]
            if named or (free and len(free) > 1):
                self.lanes[i] = (named or free)[0]

    def _put_back(self, indices: list[int]) -> None:
        """Tests sent and not run go back to the front of their queues (live ones as a
        file of their own)."""
        assert self.collection is not None
        live = [i for i in indices if self.collection[i] in self.live_ids]
        if live:
            self.live.insert(0, live)
        self.pure[:0] = [i for i in indices if self.collection[i] not in self.live_ids]

    def _send(self, node: Any, chunk: list[int]) -> None:
        if chunk:
            self.node2pending[node].extend(chunk)
            node.send_runtest_some(chunk)
