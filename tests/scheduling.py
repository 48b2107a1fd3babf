"""How the suite runs in parallel (pytest-xdist): the live tests one at a time on one
worker, the pure tests on every worker.

The live tests (marked ``slow``) run real processes against 60 ms real-time cycles: two
live stacks at once on a 2-core machine compete for the same cores, so they never run
at the same time. The first worker runs them one after the other, from the start of the
session (their chain is the longest part of the run); the other workers take the pure
tests meanwhile, so at most one pure test runs beside a live one, and once the pure
tests are done the rest of the live chain runs alone. The workers of pure tests run at
a lower priority (:data:`PURE_NICE`), so the live processes take a core at once when
they wake. When the live chain is done, its worker takes pure tests too.

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

LIVE_IDS = "MANUS_TEST_LIVE_IDS"
"""Environment variable: the file where the workers write the ids of the live tests for
the scheduler (xdist sends the controlling process ids only, not markers)."""

MAX_WORKERS = 8
LIVE_WORKER = "gw0"
"""The worker of the live chain (another one only if it died)."""
PURE_NICE = 5
"""Niceness of the other workers: a live test's processes (niceness 0) get three times
their share of a contended core and take it at once when they wake, yet a pure test
keeps a quarter of a core when a CPU hog (niceness 0) loads every core, so its own
bounded waits still hold."""
_OWN_FILE = pytest.StashKey[str]()


def pytest_configure(config: pytest.Config) -> None:
    """In the controlling process: a file for the live tests' ids, which the workers it
    starts find in their environment. In a worker of pure tests: :data:`PURE_NICE`."""
    worker = getattr(config, "workerinput", None)
    if worker is not None and worker.get("workerid") != LIVE_WORKER:
        os.nice(PURE_NICE)
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


def tell_live(config: pytest.Config, live: list[pytest.Item]) -> None:
    """In a worker, after collection: write the ids of the live tests in the order they
    are to run: those marked ``slow(last=True)`` last, after the pure tests are done where
    the live chain is long enough (every worker collects the same tests and writes the
    same file, before it reports its collection)."""
    path = os.environ.get(LIVE_IDS)
    if hasattr(config, "workerinput") and path:
        ordered = sorted(live, key=_last)
        part = Path(f"{path}.{os.getpid()}")
        part.write_text("".join(f"{item.nodeid}\n" for item in ordered))
        part.replace(path)


def _last(item: pytest.Item) -> bool:
    mark = item.get_closest_marker("slow")
    return mark is not None and bool(mark.kwargs.get("last"))


def workers(config: pytest.Config) -> int:
    """Workers for ``-n auto``: one per CPU (at least 2: the live chain and the pure
    tests; at most :data:`MAX_WORKERS`) for the whole suite, none (one process) when the
    command line names what to run. ``PYTEST_XDIST_AUTO_NUM_WORKERS`` overrides both."""
    forced = os.environ.get("PYTEST_XDIST_AUTO_NUM_WORKERS")
    if forced:
        return int(forced)
    if config.args_source != pytest.Config.ArgsSource.TESTPATHS:
        return 0
    return min(MAX_WORKERS, max(2, os.cpu_count() or 1))


def live_ids() -> list[str]:
    """The ids the workers wrote, in the order to run (:func:`tell_live`)."""
    path = os.environ.get(LIVE_IDS)
    return Path(path).read_text().splitlines() if path else []


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
        self.live: list[int] = []
        """Live tests not sent yet (collection indices, in order)."""
        self.pure: list[int] = []
        """Pure tests not sent yet."""
        self.live_node: Any = None
        """The worker of the live chain (None: not chosen, or it died)."""
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
            order = live_ids()
            self.live_ids = set(order)
            where = {nodeid: index for index, nodeid in enumerate(self.collection)}
            self.live = [where[nodeid] for nodeid in order if nodeid in where]
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
        (self.live if item in self.live_ids else self.pure).insert(0, index)
        for node in self.nodes:
            self.check_schedule(node)

    def remove_pending_tests_from_node(self, node: Any, indices: Sequence[int]) -> None:
        """Only for work stealing, which this scheduling does not do."""
        raise NotImplementedError

    def remove_node(self, node: Any) -> str | None:
        """A worker left: at its shutdown, or crashed (its queue goes back; the test it
        was running is returned)."""
        pending = self.node2pending.pop(node)
        if node is self.live_node:
            self.live_node = None
        if not pending:
            return None
        assert self.collection is not None
        crashed = self.collection[pending.pop(0)]
        for index in reversed(pending):
            queue = self.live if self.collection[index] in self.live_ids else self.pure
            queue.insert(0, index)
        for other in self.nodes:
            self.check_schedule(other)
        return crashed

    # -- the policy --------------------------------------------------------------------------

    def check_schedule(self, node: Any) -> None:
        """Give ``node`` work: the live chain if it is (or becomes) its worker, else pure
        tests, a few at a time; shut it down when nothing is left for it."""
        if node.shutting_down or self.collection is None:
            return
        if self.live and self.live_node is None:
            ids = {n.gateway.id: n for n in self.nodes if not n.shutting_down}
            self.live_node = ids.get(LIVE_WORKER, node)
            if self.live_node is not node:
                self.check_schedule(self.live_node)
        pending = self.node2pending[node]
        if node is self.live_node and self.live:
            self._send(node, self.live, len(self.live))  # one worker, in order
            return
        if node is self.live_node and len(pending) >= 2:
            return  # still in the live chain
        if self.pure:
            if len(pending) < 2:
                share = max(2, len(self.pure) // (4 * len(self.node2pending)))
                self._send(node, self.pure, share - len(pending))
            return
        if not self.live:
            node.shutdown()  # runs what it holds, then leaves

    def _send(self, node: Any, queue: list[int], count: int) -> None:
        chunk = queue[: max(count, 0)]
        if chunk:
            del queue[: len(chunk)]
            self.node2pending[node].extend(chunk)
            node.send_runtest_some(chunk)
