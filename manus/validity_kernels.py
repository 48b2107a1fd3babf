"""Compiled kernels of the fast validity check (:mod:`manus.validity`), in numba.

The arm's bodies are cut into convex *pieces*, each ``box(e) + disk(rc) + ball(rs)`` in
its joint's frame (a box of half sizes ``e`` along its axes, grown by a disk of radius
``rc`` across its third axis and a ball of radius ``rs``): a cylinder is ``e = (0, 0, h)``
with ``rc = r``, a sphere ``rs = r``, a box ``e`` alone. The obstacles are fixed convex
primitives in the base frame (box, sphere, cylinder, capsule, half-space), each with the
clearance its class requires, and the *movers*: arm bodies a held object keeps the
``self`` clearance from, placed at each configuration (:func:`place_movers`). Both move,
so a mover's pair counts half its margin in each body's margin (what bounds how far the
body may travel), and none when the mover rides on the held body's own joint (their
distance never changes); the tightest margin is the pair's whole margin.

Each piece's distance to an obstacle is bounded from below by separating directions
(:mod:`manus.distance_bounds`): a margin is never above the true one.

Everything here is plain arrays in, numbers out, no allocation per configuration, and
indices rather than array views (a view costs more than the arithmetic here). Compiled
on first use and cached on disk (``cache=True``, in ``__pycache__`` beside this file or
``$NUMBA_CACHE_DIR``): :class:`manus.validity.ValidityChecker` calls every kernel once
when it is built, so a service pays it at start-up, never in a control cycle.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from manus.distance_bounds import apart, closest, inner, jit, piece_bound


@jit
def forward(q: np.ndarray, placements: np.ndarray, frames: np.ndarray) -> None:
    """Joint frames at ``q`` [rad] (6,): ``frames[j] = frames[j-1] @ placements[j] @
    Rz(q[j-1])``, (7, 4, 4) in the base frame (frame 0: the base)."""
    frames[0] = placements[0]
    for j in range(1, placements.shape[0]):
        c, s = math.cos(q[j - 1]), math.sin(q[j - 1])
        for r in range(3):
            a = (
                frames[j - 1, r, 0] * placements[j, 0, 0]
                + frames[j - 1, r, 1] * placements[j, 1, 0]
                + frames[j - 1, r, 2] * placements[j, 2, 0]
            )
            b = (
                frames[j - 1, r, 0] * placements[j, 0, 1]
                + frames[j - 1, r, 1] * placements[j, 1, 1]
                + frames[j - 1, r, 2] * placements[j, 2, 1]
            )
            frames[j, r, 0] = a * c + b * s
            frames[j, r, 1] = b * c - a * s
            for k in range(2, 4):
                frames[j, r, k] = (
                    frames[j - 1, r, 0] * placements[j, 0, k]
                    + frames[j - 1, r, 1] * placements[j, 1, k]
                    + frames[j - 1, r, 2] * placements[j, 2, k]
                )
            frames[j, r, 3] += frames[j - 1, r, 3]
        frames[j, 3, 0] = frames[j, 3, 1] = frames[j, 3, 2] = 0.0
        frames[j, 3, 3] = 1.0


@jit
def place(frames: np.ndarray, joint: np.ndarray, local: np.ndarray, world: np.ndarray) -> None:
    """Points ``local`` (n, 3) of joints ``joint`` (n,) into the base frame, ``world``."""
    for i in range(local.shape[0]):
        j = joint[i]
        x, y, z = local[i, 0], local[i, 1], local[i, 2]
        for r in range(3):
            world[i, r] = frames[j, r, 0] * x + frames[j, r, 1] * y + frames[j, r, 2] * z
            world[i, r] += frames[j, r, 3]


@jit
def turn(frames: np.ndarray, joint: np.ndarray, axes: np.ndarray, world: np.ndarray) -> None:
    """Axes ``axes`` (n, 3, 3) (rows) of joints ``joint`` into the base frame, ``world``."""
    for i in range(axes.shape[0]):
        j = joint[i]
        for a in range(3):
            x, y, z = axes[i, a, 0], axes[i, a, 1], axes[i, a, 2]
            for r in range(3):
                world[i, a, r] = frames[j, r, 0] * x + frames[j, r, 1] * y + frames[j, r, 2] * z


@jit
def pose(q: np.ndarray, arm: Any, scratch: Any) -> None:
    """Place every piece, body centre and cover point at ``q`` (into ``scratch``)."""
    placements, p_joint, _, p_center, p_axes, _, _, _, _, _, b_joint, b_center, _ = arm[:13]
    c_joint, _, c_local, _ = arm[13:17]
    frames, centers, axes, bodies, covers = scratch[:5]
    forward(q, placements, frames)
    place(frames, p_joint, p_center, centers)
    turn(frames, p_joint, p_axes, axes)
    place(frames, b_joint, b_center, bodies)
    place(frames, c_joint, c_local, covers)


@jit
def place_movers(frames: np.ndarray, scene: Any) -> None:
    """Place the movers (obstacles ``o`` with ``partner[o] >= 0``) at the joint frames
    ``frames``: rotation and origin from their joint's frame and local placement."""
    o_R, o_t = scene[1], scene[2]
    partner, joint, local = scene[13], scene[15], scene[16]
    for o in range(partner.shape[0]):
        if partner[o] < 0:
            continue
        j = joint[o]
        for r in range(3):
            for c in range(4):
                v = (
                    frames[j, r, 0] * local[o, 0, c]
                    + frames[j, r, 1] * local[o, 1, c]
                    + frames[j, r, 2] * local[o, 2, c]
                )
                if c < 3:
                    o_R[o, r, c] = v
                else:
                    o_t[o, r] = v + frames[j, r, 3]


@jit
def valid(q: np.ndarray, arm: Any, scene: Any, scratch: Any) -> bool:
    """Whether every check at ``q`` is proven to keep its clearance."""
    pose(q, arm, scratch)
    place_movers(scratch[0], scene)
    _, _, _, _, _, p_e, p_rc, p_rs, p_rb, b_start, _, _, b_radius = arm[:13]
    c_radius = arm[16]
    o_kind, o_R, o_t, o_s, o_req, applies, z_kind, z_R, z_t, z_s, z_req, z_holds, o_box = scene[:13]
    _, centers, axes, bodies, covers = scratch[:5]
    for z in range(z_kind.shape[0]):
        for i in range(covers.shape[0]):
            if z_holds[z, i]:
                room = inner(z_kind, z_R, z_t, z_s, z, covers, i)
                if room - c_radius[i] - z_req[z] < 0.0:
                    return False
    for b in range(b_radius.shape[0]):
        for o in range(o_kind.shape[0]):
            if not applies[b, o]:
                continue
            need = o_req[o]
            if apart(o_box, o, bodies, b, b_radius[b] + need):
                continue
            d, _, _, _ = closest(o_kind, o_R, o_t, o_s, o, bodies[b, 0], bodies[b, 1], bodies[b, 2])
            if d - b_radius[b] >= need:
                continue
            for i in range(b_start[b], b_start[b + 1]):
                got = piece_bound(
                    i, centers, axes, p_e, p_rc, p_rs, p_rb, o_kind, o_R, o_t, o_s, o, need
                )
                if got < need:
                    return False
    return True


@jit
def _keep_in(arm: Any, scene: Any, covers: np.ndarray, free: np.ndarray) -> Any:
    """Each body's margin to the keep-in zones into ``free`` (B,) (inf: none), and the
    tightest of them: margin [m], body (-1: a static one), ``O + z``."""
    _, c_body, _, c_radius = arm[13:17]
    z_kind, z_R, z_t, z_s, z_req, z_holds = scene[6:12]
    n_obstacles = scene[0].shape[0]
    tight, tight_body, tight_other = math.inf, -1, -1
    free[:] = math.inf
    for z in range(z_kind.shape[0]):
        for i in range(covers.shape[0]):
            if z_holds[z, i]:
                room = inner(z_kind, z_R, z_t, z_s, z, covers, i)
                m = room - c_radius[i] - z_req[z]
                b = c_body[i]
                if b >= 0 and m < free[b]:
                    free[b] = m
                if m < tight:
                    tight, tight_body, tight_other = m, b, n_obstacles + z
    return tight, tight_body, tight_other


@jit
def margins(q: np.ndarray, arm: Any, scene: Any, scratch: Any, free: np.ndarray, cap: float) -> Any:
    """Each body's margin at ``q`` into ``free`` (B,) [m], a lower bound, at most ``cap``
    (pairs that cannot come under it are skipped: a cap makes it cheaper); returns the
    tightest margin of all, its body (-1: a static one) and what it is kept from (an
    obstacle, ``O + z`` for keep-in zone ``z``, -1 when it is the cap)."""
    pose(q, arm, scratch)
    place_movers(scratch[0], scene)
    _, _, _, _, _, p_e, p_rc, p_rs, p_rb, b_start, _, _, b_radius = arm[:13]
    o_kind, o_R, o_t, o_s, o_req, applies = scene[:6]
    o_box, partner = scene[12], scene[13]
    _, centers, axes, bodies, covers = scratch[:5]
    n_obstacles = o_kind.shape[0]
    tight, tight_body, tight_other = _keep_in(arm, scene, covers, free)
    hint = scratch[6]
    for b in range(b_radius.shape[0]):
        best, other = min(free[b], cap), -1
        # The obstacle nearest this body last time first: a small bound early lets
        # the boxes and bounding spheres skip most other pairs.
        first = hint[b]
        for n in range(-1, n_obstacles):
            o = first if n < 0 else n
            if o < 0 or not applies[b, o] or (n >= 0 and o == first) or partner[o] >= 0:
                continue
            need = o_req[o]
            if apart(o_box, o, bodies, b, b_radius[b] + need + best):
                continue
            d, _, _, _ = closest(o_kind, o_R, o_t, o_s, o, bodies[b, 0], bodies[b, 1], bodies[b, 2])
            if d - b_radius[b] - need >= best:
                continue  # the body's bounding sphere already leaves more
            for i in range(b_start[b], b_start[b + 1]):
                got = (
                    piece_bound(
                        i, centers, axes, p_e, p_rc, p_rs, p_rb, o_kind, o_R, o_t, o_s, o,
                        best + need,
                    )
                    - need
                )  # fmt: skip
                if got < best:
                    best, other = got, o
        if other >= 0:
            hint[b] = other
        if best < free[b]:
            free[b] = best
            if best < tight:
                tight, tight_body, tight_other = best, b, other
        got, mover = _movers(b, arm, scene, scratch, free)
        if got < tight:
            tight, tight_body, tight_other = got, b, mover
    return tight, tight_body, tight_other


@jit
def _movers(b: int, arm: Any, scene: Any, scratch: Any, free: np.ndarray) -> Any:
    """Body ``b``'s margins to the movers it is checked against (it is a held one),
    lower bounds: half of each (none for a rigid pair) lowers both bodies' margins in
    ``free``; returns the smallest [m] and its mover (-1: none)."""
    _, _, _, _, _, p_e, p_rc, p_rs, p_rb, b_start = arm[:10]
    o_kind, o_R, o_t, o_s, o_req, applies = scene[:6]
    partner, rigid = scene[13], scene[14]
    _, centers, axes = scratch[:3]
    tight, which = math.inf, -1
    for o in range(partner.shape[0]):
        if partner[o] < 0 or not applies[b, o]:
            continue
        got = math.inf
        for i in range(b_start[b], b_start[b + 1]):
            bound = piece_bound(
                i, centers, axes, p_e, p_rc, p_rs, p_rb, o_kind, o_R, o_t, o_s, o, math.inf
            )
            got = min(got, bound - o_req[o])
        if got < tight:
            tight, which = got, o
        if not rigid[o]:
            half = 0.5 * got if got > 0.0 else got
            c = partner[o]
            free[b] = min(free[b], half)
            free[c] = min(free[c], half)
    return tight, which


@jit
def valid_batch(Q: np.ndarray, arm: Any, scene: Any, scratch: Any, out: np.ndarray) -> None:
    """:func:`valid` at each row of ``Q`` (n, 6) into ``out`` (n,)."""
    for k in range(Q.shape[0]):
        out[k] = valid(Q[k], arm, scene, scratch)


@jit
def margins_batch(
    Q: np.ndarray,
    arm: Any,
    scene: Any,
    scratch: Any,
    free: np.ndarray,
    tight: np.ndarray,
    which: np.ndarray,
    cap: float,
) -> None:
    """:func:`margins` at each row of ``Q`` (n, 6): ``free`` (n, B), ``tight`` (n,),
    ``which`` (n, 2) (body, other)."""
    for k in range(Q.shape[0]):
        m, b, o = margins(Q[k], arm, scene, scratch, free[k], cap)
        tight[k] = m
        which[k, 0] = b
        which[k, 1] = o
