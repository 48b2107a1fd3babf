"""The simulator's true state as a bus message (:class:`schemas.state.SimTruth`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from manus.kinematics import fk
from manus.orientation import matrix_to_ypr
from manus.protocol import JOINT_UNIT_DEG
from schemas.state import SimTruth
from schemas.target import TargetTruth
from services.simulator.arm import ArmModel, ArmState, StepResult, motor_to_dh_deg

if TYPE_CHECKING:
    from services.simulator.object_world import ObjectWorld


def make_truth(
    model: ArmModel,
    state: ArmState,
    t_ns: int,
    seq: int,
    record: ContactRecord | None = None,
    world: ObjectWorld | None = None,
    target: TargetTruth | None = None,
) -> SimTruth:
    """The truth of ``state`` at ``t_ns`` (``record``: the contacts so far; ``world``: the
    objects, their contacts and the held object's clearances; ``target``: the moving
    target's truth at ``t_ns``).

    ``q_true`` are the belt-side joint angles (backlash, joint 1 scale error); ``q_reported``
    the DH angles of the encoder readings (motor angles quantised to 0.1 deg) at the same
    instant; the pose is the forward kinematics of ``q_true``; ``qd_true`` the motor speeds
    through the joint map's linear part (the belts' play aside).
    """
    qd = motor_to_dh_deg(state.speed_deg_s) - motor_to_dh_deg(np.zeros(6))
    q_true = np.radians(model.q_true_deg(state))
    counts = np.round(state.motor_deg / JOINT_UNIT_DEG) * JOINT_UNIT_DEG
    q_reported = np.radians(motor_to_dh_deg(counts))
    T = fk(q_true, model.config.arm)
    now = model.contacts.distance(np.degrees(q_true), state.gripper_mm)
    record = record or ContactRecord()
    lowest = record.min_clearance
    if now is not None:
        lowest = now.distance if lowest is None else min(lowest, now.distance)
    person = record.min_person
    if now is not None and now.person is not None:
        person = now.person if person is None else min(person, now.person)
    objects, held = [], None
    if world is not None and world.objects:
        objects = world.truth(t_ns, np.degrees(q_true), state.gripper_mm)
        held = world.contacts.held_clearance
    return SimTruth(
        stamp_ns=t_ns,
        seq=seq,
        q_true=[float(v) for v in q_true],
        q_reported=[float(v) for v in q_reported],
        gripper=state.gripper_mm / 1000.0,
        xyz=[float(v) for v in T[:3, 3]],
        ypr=[float(v) for v in matrix_to_ypr(T[:3, :3])],
        qd_true=[float(v) for v in np.radians(qd)],
        clearance=None if now is None else now.distance,
        clearance_pair="" if now is None else now.pair,
        min_clearance=lowest,
        contacts=record.contacts,
        contact=record.last,
        objects=objects,
        object_contacts=world.contacts.contacts() if world is not None else [],
        held_clearance=None if held is None else held[0],
        held_clearance_pair="" if held is None else held[1],
        held_min_person=world.contacts.held_min_person if world is not None else None,
        person_clearance=None if now is None else now.person,
        person_pair="" if now is None else now.person_pair,
        min_person_clearance=person,
        target=target,
    )


@dataclass
class ContactRecord:
    """What the simulator's ticks saw of the scene since power-up.

    Attributes:
        min_clearance: smallest true distance at any tick [m] (None: no scene).
        contacts: ticks on which a body met an object and the arm was stopped.
        last: ``body/object`` of the last contact.
        min_person: smallest true distance to a person at any tick [m] (None: no person).
    """

    min_clearance: float | None = None
    min_person: float | None = None
    contacts: int = 0
    last: str = ""

    def update(self, result: StepResult) -> None:
        """Take in one tick's :class:`StepResult`."""
        if result.distance is not None:
            d = result.distance.distance
            self.min_clearance = d if self.min_clearance is None else min(self.min_clearance, d)
            p = result.distance.person
            if p is not None:
                self.min_person = p if self.min_person is None else min(self.min_person, p)
        if result.contact:
            self.contacts += 1
            self.last = result.contact
