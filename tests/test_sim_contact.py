"""The simulator's true distances (services/simulator/contact.py) computed in two parts,
the pairs with a person apart from the others, are exactly those of one computation over
every pair: the smallest distance and its pair, the person's and its pair, at seeded
random configurations, gripper openings and places of the head. A part that lost a pair
(or a person pair that went unasked) would show here as a distance or a contact hidden."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from manus.collision import CollisionModel
from manus.config import ArmConfig
from services.simulator.contact import ContactModel, Distance

N = 3000
"""Configurations asked (seeded); about 0.3 s."""


def _reference(model: CollisionModel, q_deg: np.ndarray) -> Distance:
    """The same figures from one computation over every pair (the model's own geometry
    data, which the contact model leaves alone)."""
    margins = model.margins(np.radians(q_deg))
    names = [f"{c.body}/{c.other}" for c in model.checks]
    persons = [k for k, c in enumerate(model.checks) if c.cls == "person"]
    k = int(np.argmin(margins))  # the first of equal smallest, as Pinocchio names it
    j = persons[int(np.argmin(margins[persons]))]
    return Distance(float(margins[k]), names[k], float(margins[j]), names[j])


def test_the_split_distances_are_those_of_every_pair_at_once() -> None:
    arm = ArmConfig()
    contacts = ContactModel("default", arm, opening=0.05)
    model = contacts.model
    assert model is not None
    head = next(o for o in model.scene.objects if o.name == "head") if model.scene else None
    assert head is not None
    rng = np.random.default_rng(25)
    lower, upper = np.degrees(arm.lower_array), np.degrees(arm.upper_array)
    person_tightest = person_touched = far = 0
    for i in range(N):
        if i % 5 == 0:  # the head moves (within the bound its kept pairs stay right for)
            pose = np.array(head.body.pose, dtype=float)
            pose[:3, 3] += rng.uniform(-0.1, 0.1, 3)
            contacts.move("head", pose)
        q = rng.uniform(lower, upper)
        opening_mm = float(rng.uniform(0.0, arm.gripper_max * 1e3))
        found = contacts.distance(q, opening_mm)
        assert found == _reference(model, q), f"configuration {i}: q = {q.tolist()} deg"
        assert found.person is not None
        person_tightest += found.pair == found.person_pair
        person_touched += found.person <= 0.0
        far += found.person > 0.2
    # Both parts decided the tightest at times, and the person was both touched and far.
    assert 0 < person_tightest < N
    assert person_touched > 0 and far > 0


TWINS = """version: 1
mount: {{xyz_mm: [350, -420, 1000]}}
objects:
  - {{name: {0}, class: {1}, shape: sphere, radius_mm: 60, xyz_mm: [750, -420, 900]}}
  - {{name: {2}, class: {3}, shape: sphere, radius_mm: 60, xyz_mm: [750, -420, 900]}}
"""
"""Two equal spheres in one place, of two classes: every body is as far from one as from
the other, so the smallest distance is a tie between a person pair and another."""


@pytest.mark.parametrize("person_first", [True, False])
def test_a_tie_goes_to_the_first_pair_as_in_one_computation(
    tmp_path: Path, person_first: bool
) -> None:
    twins = ("twin_p", "person", "twin_e", "environment")
    if not person_first:
        twins = twins[2:] + twins[:2]
    scene = tmp_path / "twins.yaml"
    scene.write_text(TWINS.format(*twins))
    arm = ArmConfig()
    contacts = ContactModel(str(scene), arm)
    model = contacts.model
    assert model is not None
    rng = np.random.default_rng(26)
    lower, upper = np.degrees(arm.lower_array), np.degrees(arm.upper_array)
    ties = 0
    for _ in range(500):
        q = rng.uniform(lower, upper)
        found = contacts.distance(q, 0.0)
        assert found == _reference(model, q)
        body, other = found.pair.split("/")
        if other.startswith("twin"):
            twin = "twin_e" if other == "twin_p" else "twin_p"
            margins = model.margins(np.radians(q))
            rows = {f"{c.body}/{c.other}": k for k, c in enumerate(model.checks)}
            assert margins[rows[f"{body}/{twin}"]] == found.distance  # a tie indeed
            ties += 1
    assert ties > 0
