"""The suite's own xdist scheduling (tests/scheduling.py): the live tests a file at a time
in two lanes from the start (the second after the pure tests when no other worker takes
them), the pure tests on the other workers, every test run once."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace

import pytest

from tests import scheduling
from tests.scheduling import LIVE_IDS, LiveApartScheduling


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
    collection: list[str], live: list[str], workers: int, tmp_path: Path, mp: pytest.MonkeyPatch
) -> tuple[dict[str, list[str]], list[tuple[str, str]]]:
    """Schedule ``collection`` on ``workers`` fake workers that each run the tests they
    hold, one at a time, keeping one back until told more or to shut down (as xdist's do);
    the tests each one ran, and the (worker, test) order of the whole run."""
    ids = tmp_path / "live.txt"  # as tell_live writes it: a unit per file here
    ids.write_text("".join(f"{n.split('::')[0]}\t{n}\n" for n in live))
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
    for _ in range(10 * len(collection)):
        runnable = [n for n in nodes if len(n.sent) - done[n.name] >= (1 if n.shutting_down else 2)]
        if not runnable:
            break
        node = runnable[len(order) % len(runnable)]  # interleave the workers
        index = node.sent[done[node.name]]
        done[node.name] += 1
        ran[node.name].append(collection[index])
        order.append((node.name, collection[index]))
        sched.mark_test_complete(node, index)
    assert sched.tests_finished and not sched.has_pending
    return ran, order


LIVE = ["a.py::x", "a.py::y", *(f"f{i:02}.py::x" for i in range(12)), "z.py::x", "z.py::y"]


def test_two_lanes_take_live_units_in_order_and_every_test_runs_once(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    collection = [f"p{i}" for i in range(4)] + LIVE + [f"q{i}" for i in range(4)]
    ran, order = _run(collection, LIVE, 3, tmp_path, monkeypatch)
    assert sorted(t for tests in ran.values() for t in tests) == sorted(collection)  # once each
    firsts = {ran["gw0"][0], ran["gw1"][0]}
    assert "a.py::x" in firsts and firsts <= set(LIVE)  # both lanes from the start
    assert not set(ran["gw2"]) & set(LIVE)  # the worker of pure tests
    assert set(ran["gw1"]) <= set(LIVE) and ran["gw1"]  # the second lane
    first_pure = next(i for i, (w, t) in enumerate(order) if t[0] in "pq")
    assert ("gw1", ran["gw1"][0]) in order[: first_pure + 4]  # from the start, beside them
    for lane in ("gw0", "gw1"):  # units in their order, from the front
        files = [t.split("::")[0] for t in ran[lane] if t in LIVE]
        assert files == sorted(files)
    assert {t.split("::")[0] for t in ran["gw0"] if t in LIVE}.isdisjoint(
        {t.split("::")[0] for t in ran["gw1"]}
    )


def test_two_workers_the_second_lane_takes_the_pure_tests_first(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    collection = [f"p{i}" for i in range(30)] + LIVE
    ran, _ = _run(collection, LIVE, 2, tmp_path, monkeypatch)
    assert sorted(t for tests in ran.values() for t in tests) == sorted(collection)
    assert ran["gw0"][:2] == ["a.py::x", "a.py::y"]
    assert ran["gw1"][0].startswith("p")


def test_one_worker_runs_everything(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    collection = [f"t{i}" for i in range(9)]
    ran, _ = _run(collection, ["t1", "t2"], 1, tmp_path, monkeypatch)
    assert sorted(ran["gw0"]) == sorted(collection)


def test_workers_for_the_whole_suite_only(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("PYTEST_XDIST_AUTO_NUM_WORKERS", raising=False)
    whole = SimpleNamespace(args_source=pytest.Config.ArgsSource.TESTPATHS)
    named = SimpleNamespace(args_source=pytest.Config.ArgsSource.ARGS)
    monkeypatch.setattr("os.cpu_count", lambda: 2)
    assert scheduling.workers(whole) == 3  # type: ignore[arg-type]  # two lanes, one pure
    monkeypatch.setattr("os.cpu_count", lambda: 4)
    assert scheduling.workers(whole) == 5  # type: ignore[arg-type]  # two lanes, three pure
    assert scheduling.workers(named) == 0  # type: ignore[arg-type]
    monkeypatch.setenv("PYTEST_XDIST_AUTO_NUM_WORKERS", "4")
    assert scheduling.workers(named) == 4  # type: ignore[arg-type]


def _item(nodeid: str, scope: str = "function", long: bool = False) -> SimpleNamespace:
    fixture = SimpleNamespace(scope=scope, baseid="tests")
    mark = SimpleNamespace(kwargs={"long": True} if long else {})
    return SimpleNamespace(
        nodeid=nodeid,
        _fixtureinfo=SimpleNamespace(name2fixturedefs={"f": [fixture]}),
        get_closest_marker=lambda name: mark,
    )


def test_units_keep_a_module_fixture_together_and_put_the_long_ones_first() -> None:
    items = [
        _item("a.py::x"), _item("a.py::y"),  # function fixtures only: a unit each
        _item("m.py::x", "module"), _item("m.py::y", "module"), _item("m.py::z", "module"),
        _item("s.py::soak", long=True),
    ]  # fmt: skip
    got = scheduling.units(items)  # type: ignore[arg-type]
    assert got == [["s.py::soak"], ["m.py::x", "m.py::y", "m.py::z"], ["a.py::x"], ["a.py::y"]]
