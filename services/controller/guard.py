"""The controller's per-cycle collision guard (MoveIt Servo's slow-down, Kortex's zones).

Every command passes through :meth:`Guard.filter` where the controller forms it, so
trajectories, spliced (replaced) trajectories and jogs are all guarded. It predicts where
the arm will be: the joint state's snapshot at s, plus what the arm executes during
[s, s+60) ms (``JointState.applied_velocity``, already sent), plus this command during
[s+60, s+120) ms, plus the drives' run-out after it (``runout_s``, the lag). If the
clearances (the scene's, per class, and the zones) would be violated there, the
command is scaled down, or stopped; near an obstacle (margin under ``slow_zone_m``) a
motion that closes in is slowed in proportion. A motion that opens a margin is always
allowed, so an arm that starts too close can still leave.

Most cycles compute no distance at all: from the last configuration whose distances
were computed (the anchor), no point of the arm can have moved further than its joint
moves times each joint's reach (grown by the joints beyond it), and while that bound
stays under each body's margin at the anchor nothing can be violated (conservative
advancement, :class:`manus.advancement.Advancement`, compiled). An anchor takes the fast
check's margins first (:mod:`manus.validity`, lower bounds); only when they do not
prove the command (a margin under ``slow_zone_m``) does Coal compute, and the guard
decides on exact distances as it always did (those ahead only when the fast check's
bounds there do not already give the pass). The clearance a goal reports is Coal's:
computed at an anchor whose fast bound says it may be below the goal's smallest so far.

Pure: no clock, no I/O; the same inputs give the same commands.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from manus.advancement import Advancement
from manus.clearance import Clearance
from manus.collision import CollisionModel
from manus.joint_map import encoder_increments_to_dh_list
from manus.quantize import COUNT_RAD_S
from manus.validity import checker_for

_ROUNDING_M = 1e-6
"""More than a margin's rounding in ``distance - required`` [m] (a report's comparisons)."""

OPENING_M = 0.005
"""A gripper opening this much other than the model's [m]: the model follows it."""

_SAME = np.eye(6)
"""The rates the prediction takes are DH rates already: no map."""


class Verdict(NamedTuple):
    """What the guard did to one command.

    Attributes:
        counts: the motor counts to send, shape (6,) (the input's, scaled toward 0).
        scale: the factor applied (1: unchanged, 0: stopped).
        reason: why it scaled or stopped ("" when unchanged).
        clearance: the tightest clearance computed this cycle (None: none computed).
        near: when it scaled or stopped: the clearance, where the arm is now (the
            snapshot), of the check that decided it (None: unchanged).
    """

    counts: np.ndarray
    scale: float
    reason: str
    clearance: Clearance | None
    near: Clearance | None = None


class Guard:
    """Scales or stops commands that would break a clearance.

    Args:
        model: the collision model (scene, zones, the arm itself).
        cycle_s: the arm's cycle [s] (60 ms).
        runout_s: how far past its cycle a command carries the arm (drive lag) [s].
        slow_zone_m: below this margin, motions that close in are slowed in proportion [m].
    """

    def __init__(
        self,
        model: CollisionModel,
        *,
        cycle_s: float = 0.06,
        runout_s: float = 0.06,
        slow_zone_m: float = 0.03,
    ) -> None:
        self.model = model
        self.cycle_s = cycle_s
        self.runout_s = runout_s
        self.slow_zone_m = slow_zone_m
        self.advance = Advancement(checker_for(model))
        self.report_below = math.inf
        """A pass computes Coal's clearance only when it may be below this [m] (the
        smallest its caller has seen: :class:`services.controller.run_guard.RunGuard`, per goal)."""
        self.computed = 0
        """Configurations whose distances were computed (most cycles need none)."""
        self._levers = model.cover.levers()
        self._zones_at: tuple[np.ndarray, float] | None = None
        """Where the keep-in zones were last computed, and their tightest margin there [m]."""

    def filter(
        self, q: Sequence[float], applied: Sequence[float], counts: np.ndarray, opening: float
    ) -> Verdict:
        """Guard ``counts`` (motor speed steps, (6,)) for the snapshot angles ``q`` [rad]
        and the DH joint velocities in flight ``applied`` [rad/s] (6 values), gripper
        ``opening`` [m]."""
        counts = np.asarray(counts, dtype=np.int64)
        motor = counts.tolist()
        if not any(motor) and not any(applied):
            return Verdict(counts, 1.0, "", None)
        model = self.model
        if abs(model.opening - opening) > OPENING_M:  # a wider gripper: the proof is void
            model.set_opening(opening)
            self.advance.forget()
        ahead = self.cycle_s + self.runout_s
        cmd_dh = encoder_increments_to_dh_list(motor)
        rates = [d * COUNT_RAD_S for d in cmd_dh]  # the command's DH rates [rad/s]
        # The common path, proven clear from the anchor: one compiled call.
        if self.advance.proven_ahead(q, applied, rates, _SAME, self.cycle_s, ahead):
            return Verdict(counts, 1.0, "", None)
        nxt = [a + v * self.cycle_s for a, v in zip(q, applied, strict=True)]
        end = [a + r * ahead for a, r in zip(nxt, rates, strict=True)]
        return self._decide(counts, list(q), nxt, end)

    def _decide(
        self,
        counts: np.ndarray,
        q: list[float],
        nxt: list[float],
        end: list[float],
    ) -> Verdict:
        """Compute the distances: pass, slow down or stop (not proven clear already)."""
        q_s, q_next, q_end = np.array(q, dtype=float), np.array(nxt), np.array(end)
        self.computed += 1
        if self.advance.anchor_fast(q_s) >= self.slow_zone_m and self.advance.proven(nxt, end):
            return Verdict(counts, 1.0, "", self._report(q_s))  # the fast bounds prove it
        now = self._anchor_at(q_s)
        fresh = now.margin >= self.slow_zone_m and self.advance.proven(nxt, end)
        if fresh or self._bounds_pass(q_next, q_end, now.margin):
            return Verdict(counts, 1.0, "", now.clearance)  # the fresh margins prove it
        floor = min(0.0, now.margin) - 1e-4
        m_next = self._margin(q_next)
        if m_next.margin < floor:
            return self._stopped(counts, m_next, "already in flight", self._now(now, m_next, q_s))
        m_end = self._margin(q_end)
        scale = 1.0
        if m_end.margin < floor:
            # The margin along the way is about linear in the scale: aim below the root.
            span = m_next.margin - m_end.margin
            scale = max(0.0, min(1.0, 0.9 * (m_next.margin - floor) / span)) if span > 0 else 0.0
        if 0.0 < now.margin < self.slow_zone_m and m_end.margin < now.margin:
            scale = min(scale, max(0.1, now.margin / self.slow_zone_m))
        if scale >= 1.0:
            return Verdict(counts, 1.0, "", now.clearance)
        scaled = np.trunc(counts * scale).astype(np.int64)
        if scale > 0.0:
            scaled = self._at_least_one(counts, scaled, q_next)
        if scale > 0.0 and scaled.any():
            check = self._margin(self._ahead(q_next, scaled))
            if check.margin >= floor:
                reason = f"slowed to {scale:.2f}: {check.describe()} ahead"
                return Verdict(scaled, scale, reason, now.clearance, now.clearance)
        near = self._now(now, m_end, q_s)
        return self._stopped(counts, m_end, "ahead at the commanded speed", near)

    def object_moved(self, by: float) -> None:
        """A scene object moved by at most ``by`` [m]: every margin of the anchor shrinks
        by that much, so its proof stays conservative without a new distance."""
        if by > 0.0:
            self.advance.shrink(by)

    def _at_least_one(
        self, counts: np.ndarray, scaled: np.ndarray, q_next: np.ndarray
    ) -> np.ndarray:
        """``scaled`` with one count, in its direction, for every joint the command moves
        that the slow-down truncated to none, when that motion is proven clear; else
        ``scaled`` as it is.

        A count is the arm's smallest speed step (5 deg/s): a trajectory's first and last
        counts, slowed near something, would all become zero, and the motion stop there
        ("stopped ... ahead") though one count is clear. The proof: the arm reaches
        ``q_next`` whatever is sent now (the motion in flight, checked when it was sent
        and again above); from there, the fast check proves the straight joint motion to
        this command's end with the run-out continuously, on lower bounds of the margins
        (:meth:`manus.validity.ValidityChecker.motion_valid`: conservative advancement,
        every margin at least ``MOTION_FLOOR_M`` all along; no sampling).
        """
        least = np.where((counts != 0) & (scaled == 0), np.sign(counts), scaled)
        if (least == scaled).all():
            return scaled
        if self.advance.checker.motion_valid(q_next, self._ahead(q_next, least)).ok:
            return least
        return scaled

    def _ahead(self, q_next: np.ndarray, counts: np.ndarray) -> np.ndarray:
        """Where ``counts`` [motor speed steps] take the arm from ``q_next`` [rad]: this
        cycle and the run-out after it."""
        rates = np.array(encoder_increments_to_dh_list(counts.tolist())) * COUNT_RAD_S
        return np.asarray(q_next + rates * (self.cycle_s + self.runout_s))

    # --- internals ---------------------------------------------------------------------------

    def _stopped(self, counts: np.ndarray, found: Clearance, when: str, near: Clearance) -> Verdict:
        reason = f"stopped: {found.describe()} {when}"
        return Verdict(np.zeros_like(counts), 0.0, reason, found, near)

    def _now(self, now: _AnchorResult, found: Clearance, q: np.ndarray) -> Clearance:
        """The clearance at ``q`` (where the arm is) of ``found``'s check: the tightest
        one there if it is the same (most cycles), else computed."""
        if found.check == now.clearance.check:
            return now.clearance
        model = self.model
        self.computed += 1
        margins = model.margins(q)
        pairs = [(float(m), c) for m, c in zip(margins, model.checks, strict=True)]
        for margin, check in pairs + model.keep_in_margins():
            if check == found.check:
                return Clearance(margin, margin + check.required, check, 0.0, q)
        return now.clearance

    def _bounds_pass(self, q_next: np.ndarray, q_end: np.ndarray, now: float) -> bool:
        """Whether the fast check's lower bounds at ``q_next`` and ``q_end`` [rad] give
        :meth:`_decide` its pass (``now``: Coal's margin at the anchor [m]): neither below 0
        (the floor is under it), nor ``q_end``'s below ``now`` where closing is slowed.
        Exact margins, at least as large, decide the same: no Coal call (0.1-0.4 ms each)."""
        need = now if 0.0 < now < self.slow_zone_m else 0.0
        bounds = self.advance.checker.margins_batch(np.array([q_next, q_end]), cap=need)
        passed = bool(bounds.tight[0] >= 0.0 and bounds.tight[1] >= need)
        self.computed += 2 if passed else 0  # (else Coal computes the same two)
        return passed

    def _margin(self, q: np.ndarray) -> Clearance:
        self.computed += 1
        return self.model.probe(q, reach=False).best

    def _report(self, q: np.ndarray) -> Clearance | None:
        """Coal's tightest check at ``q`` when it may be below :attr:`report_below` (the
        fast bound says whether it can be), else None; ``q`` is the anchor.

        Coal computes only the bodies whose fast margin at the anchor (a lower bound of
        each of its checks where it is not negative, 10 um under Coal's) may be below
        :attr:`report_below`: the tightest of the others cannot be. A result that is not
        below it (by more than a rounding) is None, as the caller would not keep it. A
        held body's pair with an arm body that moves lives in the held body's own checks,
        and the fast check lowers both bodies' margins by a lower bound of it, so the held
        body's margin bounds it as well; its pairs on its own joint (the gripper's) no
        margin bounds: a held body with one is always computed (:attr:`CollisionModel.rigid`).
        A goal's first report (nothing to be below yet) computes first the body with the
        smallest fast margin, alone: its margin is a bound the others must be below. The
        keep-in zones are left out when they are surely above the bound (:meth:`_travel`
        from where they were last computed)."""
        below = self.report_below
        if self.advance.margin >= below:
            return None
        lower = self.advance.free
        if below == math.inf:
            alone = np.ones(len(lower), dtype=bool)
            alone[int(np.argmin(lower))] = False
            below = self.model.probe(q, reach=False, skip=alone, zones=False).best.margin
        skip = (lower >= 0.0) & (lower >= below + _ROUNDING_M) & ~self.model.rigid
        at = self._zones_at
        clear = at is not None and at[1] - self._travel(q, at[0]) >= below + _ROUNDING_M
        found = self.model.probe(q, reach=False, skip=skip, zones=not clear)
        if not clear:
            self._zones_at = (q.copy(), found.keep_in)
        best = found.best
        return best if best.margin < below + _ROUNDING_M else None

    def _travel(self, q: np.ndarray, origin: np.ndarray) -> float:
        """How far any cover point of a body can have moved from ``origin`` to ``q`` [rad]
        (:meth:`manus.body_cover.BodyCover.levers`) [m]."""
        return float((np.abs(q - origin) @ self._levers).max(initial=0.0))

    def _anchor_at(self, q: np.ndarray) -> _AnchorResult:
        best, free, reach, zones = self.model.probe(q)
        self.computed += 1
        self.advance.anchor(q, free, reach, best.margin)
        self._zones_at = (q.copy(), zones)
        return _AnchorResult(best.margin, best)


class _AnchorResult(NamedTuple):
    margin: float
    clearance: Clearance
