"""The world model: objects added, moved and removed by perception, as versioned diffs a
follower can apply; staleness with its age; jumps; malformed frames refused whole."""

from __future__ import annotations

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from manus.errors import ConfigError
from manus.world import WorldConfig, WorldModel
from manus.world_follower import FULL, WorldError, apply_update
from schemas import endpoints as ep
from schemas.objects import ObservedObject, Perception, WorldObject, WorldUpdate
from services.planner.config import PlannerConfig
from services.planner.core import PlannerCore
from services.planner.wiring import WIRING

S = 1_000_000_000
"""One second [ns]."""


def seen(name: str, x: float = 1.0, cls: str = "cup") -> ObservedObject:
    return ObservedObject(
        id=name,
        cls=cls,
        shape="cylinder",
        size=[0.04, 0.1],
        xyz=[x, -0.2, 0.79],
        ypr=[0.0, 0.0, 0.0],
        confidence=0.9,
    )


def frame(t_s: float, *objects: ObservedObject, removed: tuple[str, ...] = ()) -> Perception:
    return Perception(
        stamp_ns=round(t_s * S),
        seq=round(t_s * 10),
        source="camera",
        objects=list(objects),
        removed=list(removed),
    )


def diffs(updates: list[WorldUpdate]) -> list[WorldUpdate]:
    return [u for u in updates if u.base_version != FULL]


def test_add_move_remove_make_one_versioned_diff_each() -> None:
    world = WorldModel()
    first = world.observe(frame(0.1, seen("cup"), seen("phone", cls="phone")))
    (add,) = diffs(first)
    assert (add.version, add.base_version) == (1, 0)
    assert [o.id for o in add.objects] == ["cup", "phone"]
    assert first[-1].base_version == FULL  # the first whole set goes out at once
    (move,) = diffs(world.observe(frame(0.2, seen("cup", 1.01))))
    assert (move.version, move.base_version, [o.id for o in move.objects]) == (2, 1, ["cup"])
    assert move.objects[0].xyz[0] == 1.01 and move.objects[0].stamp_ns == round(0.2 * S)
    (gone,) = diffs(world.observe(frame(0.3, removed=("phone", "never-seen"))))
    assert (gone.version, gone.removed, gone.objects) == (3, ["phone"], [])
    assert sorted(world.objects) == ["cup"]


def test_a_stale_object_removed_is_gone() -> None:
    world = WorldModel(WorldConfig(stale_after_s=1.0))
    world.observe(frame(1.0, seen("cup")))
    (gone,) = diffs(world.observe(frame(2.5, removed=("cup",))))
    assert (gone.removed, gone.objects) == (["cup"], [])
    assert world.objects == {}


def test_an_older_frame_does_not_move_an_object_back() -> None:
    world = WorldModel()
    world.observe(frame(0.5, seen("cup", 1.0)))
    assert diffs(world.observe(frame(0.4, seen("cup", 1.2)))) == []
    assert world.objects["cup"].xyz[0] == 1.0 and world.version == 1


def test_an_object_not_observed_goes_stale_with_its_age() -> None:
    world = WorldModel(WorldConfig(stale_after_s=2.0))
    world.observe(frame(1.0, seen("cup"), seen("bottle", cls="bottle")))
    (bottle,) = diffs(world.observe(frame(3.0, seen("bottle", cls="bottle"))))
    assert [(o.id, o.stale) for o in bottle.objects] == [("bottle", False)]  # 2 s: not yet
    (stale,) = diffs(world.observe(frame(3.2)))  # nothing seen, but the time moved on
    assert [(o.id, o.stale) for o in stale.objects] == [("cup", True)]
    assert stale.stale_after_s == 2.0
    (bottle,) = diffs(world.observe(frame(3.3, seen("bottle", cls="bottle"))))
    assert [(o.id, o.stale) for o in bottle.objects] == [("bottle", False)]  # said once
    assert world.age_s("cup") == pytest.approx(2.3)
    assert world.age_s("bottle") == pytest.approx(0.0)
    assert world.stale_reason("cup") == (
        "object 'cup' (cup) was last observed 2.3 s ago by camera (stale after 2 s)"
    )
    assert world.stale_reason("bottle") == ""
    # Perception lost: the planner judges the ages on its own clock (its joint states).
    assert world.age_s("bottle", round(6.0 * S)) == pytest.approx(2.7)
    assert "last observed 2.7 s ago" in world.stale_reason("bottle", round(6.0 * S))
    assert world.age_s("bottle", 0) == pytest.approx(0.0)  # never before the newest frame
    (fresh,) = diffs(world.observe(frame(3.6, seen("cup"))))
    assert [(o.id, o.stale) for o in fresh.objects] == [("cup", False)]
    with pytest.raises(WorldError, match=r"no object 'mug' in the world model \(known: bottle"):
        world.age_s("mug")


def test_a_jump_beyond_what_the_object_could_move_is_reported() -> None:
    world = WorldModel(WorldConfig(max_speed=1.0, jump_tolerance=0.03))
    world.observe(frame(1.0, seen("cup", 1.0)))
    (walk,) = diffs(world.observe(frame(1.1, seen("cup", 1.12))))  # 0.1 m/s x 0.1 + 0.03
    assert walk.jumps == []
    (jump,) = diffs(world.observe(frame(1.2, seen("cup", 1.40))))
    (j,) = jump.jumps
    assert (j.id, j.source) == ("cup", "camera")
    assert (j.distance, j.allowed, j.interval) == pytest.approx((0.28, 0.13, 0.1))
    assert world.objects["cup"].xyz[0] == 1.40  # kept: perception is all the stack sees
    assert world.jumps == 1


@pytest.mark.parametrize(
    ("bad", "message"),
    [
        (frame(1.0, seen("cup"), seen("cup")), "objects[1].id: 'cup' is given twice"),
        (
            frame(1.0, seen("a cup")),
            "objects[0].id: 'a cup' is not a name (letters, digits, _ and -)",
        ),
        (
            frame(1.0, ObservedObject("cup", "cup", "box", [0.1, 0.1], [0, 0, 0], [0, 0, 0], 1)),
            "objects[0].size: a box takes 3 value(s), got 2",
        ),
        (
            frame(1.0, ObservedObject("cup", "cup", "sphere", [0.0], [0, 0, 0], [0, 0, 0], 1)),
            "objects[0].size: every value must be in (0, 10] m, got [0.0]",
        ),
        (frame(1.0, seen("cup"), removed=("cup",)), "['cup'] both seen and removed"),
    ],
)
def test_a_malformed_frame_is_refused_whole(bad: Perception, message: str) -> None:
    world = WorldModel()
    world.observe(frame(0.5, seen("phone", cls="phone")))
    assert world.observe(bad) == []
    assert world.refused == 1 and world.error.endswith(message), world.error
    assert world.error.startswith("perception from 'camera' frame 10: ")
    assert sorted(world.objects) == ["phone"] and world.version == 1
    (update,) = world.observe(frame(1.6))  # the next whole set names it
    assert (update.refused, update.error) == (1, world.error)


def test_the_whole_set_goes_out_every_period_on_the_stamps() -> None:
    world = WorldModel(WorldConfig(full_every_ms=1000.0))
    world.observe(frame(1.0, seen("cup")))
    wholes = []
    for k in range(1, 31):
        wholes += [u for u in world.observe(frame(1.0 + 0.1 * k)) if u.base_version == FULL]
    assert [u.stamp_ns for u in wholes] == [2 * S, 3 * S, 4 * S]
    assert all([o.id for o in u.objects] == ["cup"] for u in wholes)


def test_room_is_limited() -> None:
    world = WorldModel(WorldConfig(max_objects=2))
    world.observe(frame(1.0, seen("a"), seen("b")))
    assert world.observe(frame(1.1, seen("c"))) == []
    assert "1 new objects, room for 0 (max_objects 2)" in world.error
    assert diffs(world.observe(frame(1.2, seen("c"), removed=("a",))))
    assert sorted(world.objects) == ["b", "c"]


def test_world_settings_are_checked() -> None:
    with pytest.raises(ConfigError, match=r"`stale_after_s` must be in \[0.01, 3600\], got 0"):
        WorldConfig(stale_after_s=0)


def test_a_follower_needs_the_version_a_diff_applies_to() -> None:
    update = WorldUpdate(stamp_ns=0, version=5, base_version=4)
    with pytest.raises(WorldError, match="applies to version 4, but version 3 is held"):
        apply_update({}, 3, update)


NAMES = st.sampled_from(["cup", "bottle", "phone", "mug"])


@st.composite
def perception_runs(draw: st.DrawFn) -> list[tuple[str, object]]:
    """A run of frames (some late, some removing, some empty)."""
    steps: list[tuple[str, object]] = []
    t = 0.0
    for _ in range(draw(st.integers(1, 25))):
        t += draw(st.floats(0.01, 1.5))
        if draw(st.booleans()):
            steps.append(("frame", frame(t)))
            continue
        late = draw(st.floats(0.0, 0.5))
        names = draw(st.lists(NAMES, unique=True, max_size=3))
        others = sorted({"cup", "bottle", "phone", "mug"} - set(names))
        gone = draw(st.lists(st.sampled_from(others), unique=True, max_size=1)) if others else []
        objects = [seen(n, draw(st.floats(0.5, 1.5))) for n in names]
        steps.append(("frame", frame(max(t - late, 0.0), *objects, removed=tuple(gone))))
    return steps


@given(perception_runs())
@settings(max_examples=150)
def test_a_follower_that_applies_every_update_holds_the_models_set(
    steps: list[tuple[str, object]],
) -> None:
    world = WorldModel(WorldConfig(stale_after_s=1.0))
    held: dict[str, WorldObject] = {}
    version = 0
    for _, value in steps:
        assert isinstance(value, Perception)
        for update in world.observe(value):
            held = apply_update(held, version, update)
            version = update.version
        assert held == world.objects and version == world.version
        for obj in world.objects.values():
            assert obj.stale == (world.age_s(obj.id) > 1.0)


def test_the_planner_keeps_the_world_model() -> None:
    core = PlannerCore(PlannerConfig(scene="none"))
    out = WIRING.feed(core, ep.PERCEPTION, frame(0.1, seen("cup")), 0)
    assert [suffix for suffix, _ in out] == [ep.OBJECTS, ep.OBJECTS]
    assert sorted(core.world.objects) == ["cup"]
