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

A piece's distance to an obstacle is bounded from below by a separating direction: for
any unit ``u``, ``dist(A, O) >= min_{a in A} u.a - max_{b in O} u.b`` (``sep(u)``). The
first ``u`` points from the obstacle's closest point to the piece's centre; each further
one from the obstacle's closest point to the piece's support point in the direction of
the obstacle (an alternating projection that comes closer to the true distance at each
step). A bound of zero or less proves nothing (the pair counts as violated), so a margin
is never above the true one: the check is conservative whatever the number of
iterations.

Everything here is plain arrays in, numbers out, no allocation per configuration, and
indices rather than array views (a view costs more than the arithmetic here). Compiled
on first use and cached on disk (``cache=True``, in ``__pycache__`` beside this file or
``$NUMBA_CACHE_DIR``): :class:`manus.validity.ValidityChecker` calls every kernel once
when it is built, so a service pays it at start-up, never in a control cycle.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, TypeVar, cast

import numba
import numpy as np

BOX, SPHERE, CYLINDER, CAPSULE, HALFSPACE = 0, 1, 2, 3, 4
"""Obstacle kinds. Sizes: box half sizes (x, y, z); sphere (r, -, -); cylinder and
capsule (r, half length, -); half-space: the solid side is local z <= 0."""

ITERATIONS = 3
"""Refinements of the separating direction per piece and obstacle (only where the
first bound does not already decide)."""

_F = TypeVar("_F", bound=Callable[..., Any])


def jit(fn: _F) -> _F:
    """numba's ``njit``, cached on disk, typed for mypy."""
    return cast(_F, numba.njit(cache=True, fastmath=False, nogil=True)(fn))


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
def closest(
    kinds: np.ndarray, Rs: np.ndarray, ts: np.ndarray, ss: np.ndarray, o: int,
    px: float, py: float, pz: float,
) -> Any:  # fmt: skip
    """Distance from ``p`` to obstacle ``o`` (<= 0: inside or on it) and the unit
    direction from the obstacle's closest point to ``p`` (zeros when inside). Indices,
    not array views: a view costs more than the arithmetic here."""
    kind = kinds[o]
    dx, dy, dz = px - ts[o, 0], py - ts[o, 1], pz - ts[o, 2]
    lx = Rs[o, 0, 0] * dx + Rs[o, 1, 0] * dy + Rs[o, 2, 0] * dz
    ly = Rs[o, 0, 1] * dx + Rs[o, 1, 1] * dy + Rs[o, 2, 1] * dz
    lz = Rs[o, 0, 2] * dx + Rs[o, 1, 2] * dy + Rs[o, 2, 2] * dz
    if kind == HALFSPACE:
        return lz, Rs[o, 0, 2], Rs[o, 1, 2], Rs[o, 2, 2]
    s0, s1, s2 = ss[o, 0], ss[o, 1], ss[o, 2]
    if kind == BOX:
        ex = lx - min(max(lx, -s0), s0)
        ey = ly - min(max(ly, -s1), s1)
        ez = lz - min(max(lz, -s2), s2)
        n = math.sqrt(ex * ex + ey * ey + ez * ez)
        if n <= 0.0:
            return max(abs(lx) - s0, abs(ly) - s1, abs(lz) - s2), 0.0, 0.0, 0.0
        d = n
    elif kind == CYLINDER:
        rho = math.sqrt(lx * lx + ly * ly)
        over_r, over_z = rho - s0, abs(lz) - s1
        if over_r <= 0.0 and over_z <= 0.0:
            return max(over_r, over_z), 0.0, 0.0, 0.0
        k = over_r / rho if over_r > 0.0 else 0.0
        ex, ey = lx * k, ly * k
        ez = math.copysign(over_z, lz) if over_z > 0.0 else 0.0
        n = math.sqrt(ex * ex + ey * ey + ez * ez)
        d = n
    else:  # sphere, capsule: around a point or a segment along z
        ex, ey = lx, ly
        ez = lz if kind == SPHERE else lz - min(max(lz, -s1), s1)
        n = math.sqrt(ex * ex + ey * ey + ez * ez)
        d = n - s0
        if d <= 0.0 or n <= 0.0:
            return d, 0.0, 0.0, 0.0
    ex, ey, ez = ex / n, ey / n, ez / n
    return (
        d,
        Rs[o, 0, 0] * ex + Rs[o, 0, 1] * ey + Rs[o, 0, 2] * ez,
        Rs[o, 1, 0] * ex + Rs[o, 1, 1] * ey + Rs[o, 1, 2] * ez,
        Rs[o, 2, 0] * ex + Rs[o, 2, 1] * ey + Rs[o, 2, 2] * ez,
    )


@jit
def _extent(
    A: np.ndarray, e: np.ndarray, rc: float, rs: float, i: int, ux: float, uy: float, uz: float
) -> float:
    """How far piece ``i`` reaches from its centre along ``u`` (its support function)."""
    a0 = A[i, 0, 0] * ux + A[i, 0, 1] * uy + A[i, 0, 2] * uz
    a1 = A[i, 1, 0] * ux + A[i, 1, 1] * uy + A[i, 1, 2] * uz
    a2 = A[i, 2, 0] * ux + A[i, 2, 1] * uy + A[i, 2, 2] * uz
    return float(
        e[i, 0] * abs(a0)
        + e[i, 1] * abs(a1)
        + e[i, 2] * abs(a2)
        + rc * math.sqrt(max(0.0, 1.0 - a2 * a2))
        + rs
    )


@jit
def piece_bound(
    i: int, C: np.ndarray, A: np.ndarray, E: np.ndarray, RC: np.ndarray, RS: np.ndarray,
    RB: np.ndarray, kinds: np.ndarray, Rs: np.ndarray, ts: np.ndarray, ss: np.ndarray,
    o: int, enough: float,
) -> float:  # fmt: skip
    """A lower bound of the distance between piece ``i`` (centres ``C``, axes ``A`` as
    rows, box half sizes ``E``, disk radii ``RC``, ball radii ``RS``, bounding radii
    ``RB``; base frame) and obstacle ``o``; refined only while it is below ``enough``."""
    cx, cy, cz = C[i, 0], C[i, 1], C[i, 2]
    rc, rs = RC[i], RS[i]
    d, ux, uy, uz = closest(kinds, Rs, ts, ss, o, cx, cy, cz)
    if d <= 0.0:
        return float(d - RB[i])
    best = float(d) - _extent(A, E, rc, rs, i, ux, uy, uz)
    for _ in range(ITERATIONS):
        if best >= enough:
            break
        # The piece's point farthest along -u (toward the obstacle).
        a0 = A[i, 0, 0] * ux + A[i, 0, 1] * uy + A[i, 0, 2] * uz
        a1 = A[i, 1, 0] * ux + A[i, 1, 1] * uy + A[i, 1, 2] * uz
        a2 = A[i, 2, 0] * ux + A[i, 2, 1] * uy + A[i, 2, 2] * uz
        wx, wy, wz = ux - a2 * A[i, 2, 0], uy - a2 * A[i, 2, 1], uz - a2 * A[i, 2, 2]
        wn = math.sqrt(wx * wx + wy * wy + wz * wz)
        k = rc / wn if wn > 1e-12 else 0.0
        g0 = E[i, 0] * math.copysign(1.0, a0)
        g1 = E[i, 1] * math.copysign(1.0, a1)
        g2 = E[i, 2] * math.copysign(1.0, a2)
        # Offsets from the centre to the support point.
        ox = -(g0 * A[i, 0, 0] + g1 * A[i, 1, 0] + g2 * A[i, 2, 0]) - k * wx - rs * ux
        oy = -(g0 * A[i, 0, 1] + g1 * A[i, 1, 1] + g2 * A[i, 2, 1]) - k * wy - rs * uy
        oz = -(g0 * A[i, 0, 2] + g1 * A[i, 1, 2] + g2 * A[i, 2, 2]) - k * wz - rs * uz
        d2, vx, vy, vz = closest(kinds, Rs, ts, ss, o, cx + ox, cy + oy, cz + oz)
        if d2 <= 0.0:
            break
        # sep(v): the piece's lowest point along v minus the obstacle's highest (the
        # closest point to the support point, where v is normal to the obstacle).
        bound = d2 - (vx * ox + vy * oy + vz * oz) - _extent(A, E, rc, rs, i, vx, vy, vz)
        best = max(best, bound)
        ux, uy, uz = vx, vy, vz
    return best


@jit
def _apart(boxes: np.ndarray, o: int, P: np.ndarray, i: int, gap: float) -> bool:
    """Whether point ``P[i]`` is further than ``gap`` [m] outside obstacle ``o``'s box in
    the base frame (``boxes`` (O, 2, 3): low and high corners), along one axis: six
    comparisons settle most pairs before any distance."""
    for r in range(3):  # noqa: SIM110 (a loop: numba compiles no generator into any())
        if P[i, r] - boxes[o, 1, r] >= gap or boxes[o, 0, r] - P[i, r] >= gap:
            return True
    return False


@jit
def inner(
    kinds: np.ndarray, Rs: np.ndarray, ts: np.ndarray, ss: np.ndarray, z: int, P: np.ndarray, i: int
) -> float:
    """Distance from point ``P[i]`` to the boundary of convex zone ``z``, negative
    outside [m] (a lower bound of it outside)."""
    dx, dy, dz = P[i, 0] - ts[z, 0], P[i, 1] - ts[z, 1], P[i, 2] - ts[z, 2]
    lx = Rs[z, 0, 0] * dx + Rs[z, 1, 0] * dy + Rs[z, 2, 0] * dz
    ly = Rs[z, 0, 1] * dx + Rs[z, 1, 1] * dy + Rs[z, 2, 1] * dz
    lz = Rs[z, 0, 2] * dx + Rs[z, 1, 2] * dy + Rs[z, 2, 2] * dz
    s0, s1, s2 = ss[z, 0], ss[z, 1], ss[z, 2]
    kind = kinds[z]
    if kind == BOX:
        return float(min(s0 - abs(lx), s1 - abs(ly), s2 - abs(lz)))
    if kind == SPHERE:
        return float(s0 - math.sqrt(lx * lx + ly * ly + lz * lz))
    if kind == CYLINDER:
        return float(min(s0 - math.sqrt(lx * lx + ly * ly), s1 - abs(lz)))
    along = lz - min(max(lz, -s1), s1)
    return float(s0 - math.sqrt(lx * lx + ly * ly + along * along))


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
            if _apart(o_box, o, bodies, b, b_radius[b] + need):
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
            if _apart(o_box, o, bodies, b, b_radius[b] + need + best):
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
