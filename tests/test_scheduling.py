"""The suite's own xdist scheduling (tests/scheduling.py): the live tests in lanes, a
unit at a time, the pure tests on the other workers, every test run once."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from tests import scheduling
from tests.scheduling import LANES, LIVE_IDS, LiveApartScheduling


@dataclass(eq=False)  # hashed by identity, as the scheduler keys its workers
class FakeWorker:
    """What the scheduler uses of xdist's WorkerController."""

    name: str
    sent: list[int] = field(default_factory=list)
    shutting_down: bool = False

    @property
    def gateway(self) -> SimpleNamespace:
        return SimpleNamespace(id=self.name)

    def send_runtest_some(self, indices: list[int]) -> None:
        self.sent += indices

    def shutdown(self) -> None:
        self.shutting_down = True


def _run(
    collection: list[str],
    live: list[list[str]],
    workers: int,
    tmp_path: Path,
    mp: pytest.MonkeyPatch,
) -> tuple[dict[str, list[str]], list[tuple[str, str]], int]:
    """Schedule ``collection`` (``live``: its live units, in order) on ``workers`` fake
    workers that each run the tests they hold, one at a time, keeping one back until told
    more or to shut down (as xdist's do); the tests each one ran, the (worker, test) order
    of the whole run, and the most live tests held to run at once."""
    ids = tmp_path / "live.txt"
    ids.write_text("".join(f"{u}\t{n}\n" for u, unit in enumerate(live) for n in unit))
    mp.setenv(LIVE_IDS, str(ids))
    config = SimpleNamespace(getoption=lambda name: None)
    mp.setattr("xdist.workermanage.parse_tx_spec_config", lambda c: ["popen"] * workers)
    sched = LiveApartScheduling(config, SimpleNamespace(livesched=lambda *a: None))  # type: ignore[arg-type]
    nodes = [FakeWorker(f"gw{i}") for i in reversed(range(workers))]  # gw0 not first
    for node in nodes:
        sched.add_node(node)
        sched.add_node_collection(node, collection)
    sched.schedule()
    ran: dict[str, list[str]] = {n.name: [] for n in nodes}
    order: list[tuple[str, str]] = []
    done = {n.name: 0 for n in nodes}
    flat = {t for unit in live for t in unit}
    most = 0
    for _ in range(10 * len(collection)):
        runnable = [n for n in nodes if len(n.sent) - done[n.name] >= (1 if n.shutting_down else 2)]
        if not runnable:
            break
        most = max(most, sum(collection[n.sent[done[n.name]]] in flat for n in runnable))
        node = runnable[len(order) % len(runnable)]  # interleave the workers
        index = node.sent[done[node.name]]
        done[node.name] += 1
        ran[node.name].append(collection[index])
        order.append((node.name, collection[index]))
        sched.mark_test_complete(node, index)
    assert sched.tests_finished and not sched.has_pending
    return ran, order, most


def test_live_units_run_on_the_lanes_each_on_one_lane_in_order_every_test_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv(LANES, "3")
    collection = [f"t{i}" for i in range(60)]
    live = [["t5"], ["t10", "t11", "t12", "t13"], ["t3"], ["t17"], ["t30"], ["t40", "t41"]]
    ran, order, most = _run(collection, live, 5, tmp_path, monkeypatch)
    assert sorted(t for tests in ran.values() for t in tests) == sorted(collection)  # once each
    lanes = {"gw0", "gw1", "gw2"}
    flat = [t for unit in live for t in unit]
    assert {w for w, t in order if t in flat} <= lanes  # live tests only on the lanes
    assert most == 3  # three at once, never more
    for unit in live:  # a unit on one lane, in its order
        (lane,) = {w for w, t in order if t in unit}
        assert [t for t in ran[lane] if t in unit] == unit
    assert next(t for _, t in order if t in flat) == "t5"  # the first unit starts first
    # each lane holds the test it runs and the next one (xdist's workers need it), so a
    # lane takes the next unit as it starts the last test of its own
    assert sorted(ran[lane][0] for lane in lanes) == ["t3", "t30", "t5"]
    assert {t for t in ran["gw3"] + ran["gw4"]} <= set(collection) - set(flat)


def test_one_lane_is_one_chain(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(LANES, "1")
    collection = [f"t{i}" for i in range(40)]
    live = [["t3"], ["t17", "t30"], ["t5"]]
    ran, _, _ = _run(collection, live, 2, tmp_path, monkeypatch)
    assert ran["gw0"][:4] == ["t3", "t17", "t30", "t5"]  # from the start, in order
    assert not set(ran["gw1"]) & {"t3", "t17", "t30", "t5"}


def test_one_worker_runs_everything(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    collection = [f"t{i}" for i in range(9)]
    ran, _, _ = _run(collection, [["t1"], ["t2"]], 1, tmp_path, monkeypatch)
    assert sorted(ran["gw0"]) == sorted(collection)


def test_more_lanes_than_live_units(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv(LANES, "3")
    collection = [f"t{i}" for i in range(12)]
    ran, _, _ = _run(collection, [["t4"]], 4, tmp_path, monkeypatch)
    assert sorted(t for tests in ran.values() for t in tests) == sorted(collection)


def _item(nodeid: str, module: str, scopes: list[str], long: bool = False) -> Any:
    defs = {f"f{i}": [SimpleNamespace(scope=s, baseid="tests")] for i, s in enumerate(scopes)}
    defs["browser"] = [SimpleNamespace(scope="session", baseid="")]  # a plugin's: not counted
    mark = SimpleNamespace(kwargs={"long": True} if long else {})
    return SimpleNamespace(
        nodeid=nodeid,
        module=SimpleNamespace(__name__=module),
        _fixtureinfo=SimpleNamespace(name2fixturedefs=defs),
        get_closest_marker=lambda name: mark,
    )


def test_units_keep_a_modules_shared_fixture_on_one_lane_longest_first() -> None:
    items = [
        _item("a.py::one", "a", ["function"]),
        _item("b.py::one", "b", ["module", "function"]),
        _item("c.py::soak", "c", ["function"], long=True),
        _item("a.py::two", "a", ["function"]),
        _item("b.py::two", "b", ["module"]),
    ]
    assert scheduling.units(items) == [
        ["c.py::soak"],
        ["b.py::one", "b.py::two"],
        ["a.py::one"],
        ["a.py::two"],
    ]


def test_workers_for_the_whole_suite_only(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("PYTEST_XDIST_AUTO_NUM_WORKERS", raising=False)
    monkeypatch.setenv(LANES, "3")
    monkeypatch.setattr("os.cpu_count", lambda: 2)
    whole = SimpleNamespace(args_source=pytest.Config.ArgsSource.TESTPATHS)
    named = SimpleNamespace(args_source=pytest.Config.ArgsSource.ARGS)
    assert scheduling.workers(whole) == 5  # type: ignore[arg-type]  # 3 lanes, 2 of pure tests
    assert scheduling.workers(named) == 0  # type: ignore[arg-type]
    assert [scheduling.is_lane(f"gw{i}", 5) for i in range(5)] == [True] * 3 + [False] * 2
    monkeypatch.setenv("PYTEST_XDIST_AUTO_NUM_WORKERS", "3")
    assert scheduling.workers(named) == 3  # type: ignore[arg-type]
    assert scheduling.live_lanes(3) == 2 and scheduling.live_lanes(1) == 1
