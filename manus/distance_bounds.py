"""Lower bounds of the distance between a convex piece and a convex primitive, compiled
with numba (the fast validity check's geometry: :mod:`manus.validity_kernels`).

A *piece* is ``box(e) + disk(rc) + ball(rs)`` about its centre, its axes as rows (a box
of half sizes ``e`` along its axes, grown by a disk of radius ``rc`` across its third
axis and a ball of radius ``rs``): a cylinder's slice is ``e = (0, 0, h)`` with ``rc =
r``, a capsule's ``rs = r`` instead, a sphere ``rs = r``, a box ``e`` alone. A
*primitive* is a box, sphere, cylinder, capsule or half-space, placed by a rotation and
an origin.

A piece's distance to a primitive is bounded from below by a separating direction: for
any unit ``u``, ``dist(A, O) >= min_{a in A} u.a - max_{b in O} u.b`` (``sep(u)``). The
first ``u`` points from the primitive's closest point to the piece's centre; each further
one from the primitive's closest point to the piece's support point in the direction of
the primitive (an alternating projection that comes closer to the true distance at each
step). A bound of zero or less proves nothing (the pair counts as violated), so a bound
is never above the true distance, whatever the number of iterations.

Plain arrays in, numbers out, indices rather than array views (a view costs more than
the arithmetic here); compiled on first use and cached on disk (``cache=True``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any, TypeVar, cast

import numba
import numpy as np

BOX, SPHERE, CYLINDER, CAPSULE, HALFSPACE = 0, 1, 2, 3, 4
"""Primitive kinds. Sizes: box half sizes (x, y, z); sphere (r, -, -); cylinder and
capsule (r, half length, -); half-space: the solid side is local z <= 0."""

ITERATIONS = 3
"""Refinements of the separating direction per piece and obstacle (only where the
first bound does not already decide)."""

_F = TypeVar("_F", bound=Callable[..., Any])


def jit(fn: _F) -> _F:
    """numba's ``njit``, cached on disk, typed for mypy."""
    return cast(_F, numba.njit(cache=True, fastmath=False, nogil=True)(fn))


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
def apart(boxes: np.ndarray, o: int, P: np.ndarray, i: int, gap: float) -> bool:
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
