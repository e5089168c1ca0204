"""Muscle path kinematics: lengths, lengthening velocities and moment arms of all muscles.

A path is a chain of sites; between two sites it may wrap over a sphere or an infinite
cylinder, optionally steered by a side-site, exactly as MuJoCo's spatial tendons
(`mju_wrap`, `mj_tendon`): tangent points are found in the plane of the wrap (sphere:
the plane through the centre and both end points; cylinder: the plane normal to its
axis, the height interpolated along the path); the inside-wrap variant is used when the
side-site lies inside the surface. The geometry is our own, computed from the poses of
the Drake plant's bodies; MuJoCo is only the test oracle.

Moment arms are `-dL/dq`. The length gradient is the sum over straight segments of the
unit segment direction dotted with the difference of the end-point Jacobians, where
wrap tangent points move with the wrap surface's body; for a taut (shortest) path the
wrapped arc contributes nothing to first order.

The kernel is compiled with numba (one pass over sites, wraps and segments, ~20 us for
210 muscles); everything else here is set-up.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numba
import numpy as np

from trunk_drake.model.spec import ModelSpec

MINVAL = 1e-15  # MuJoCo's mjMINVAL


@dataclass
class PathState:
    """Muscle-tendon lengths (m), lengthening velocities (m/s) and moment arms (m or m/rad)."""

    lengths: np.ndarray  # (n_muscles,)
    moment_arms: np.ndarray  # (n_muscles, n_coordinates), = -dL/dq
    velocities: np.ndarray | None = None  # (n_muscles,), = -moment_arms @ v


@dataclass
class PathPoints:
    """World points of all muscle paths at one pose (for drawing; see `MusclePaths.routes`)."""

    sites: np.ndarray  # (n_sites, 3) the path sites, in `MusclePaths` site order
    tangents: np.ndarray  # (n_wraps, 2, 3) where each wrapped stretch meets and leaves its surface
    wrap_lengths: np.ndarray  # (n_wraps,) arc length on the surface; -1 where the path misses it (tangents = its first site)


@dataclass(frozen=True)
class PathLayout:
    """How muscle paths are drawn: per muscle its route, and where sites and wrap surfaces sit.

    A route is a sequence of ("site", i) and ("wrap", h); a wrap stands between two sites.
    Bodies are indices into the body list given to `MusclePaths`.
    """

    routes: tuple[tuple[tuple[str, int], ...], ...]
    site_body: np.ndarray  # (n_sites,)
    site_local: np.ndarray  # (n_sites, 3) in the body frame
    wrap_body: np.ndarray  # (n_wraps,)
    wrap_pos: np.ndarray  # (n_wraps, 3) centre in the body frame
    wrap_rot: np.ndarray  # (n_wraps, 3, 3) orientation in the body frame (cylinder axis = local z)
    wrap_radius: np.ndarray  # (n_wraps,)
    wrap_cylinder: np.ndarray  # (n_wraps,) bool


def quat_matrix(q) -> np.ndarray:
    """Rotation matrix of a unit quaternion (w, x, y, z)."""
    w, x, y, z = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


# ---------------------------------------------------------------- MuJoCo wrapping (scalar)

_jit = numba.njit(cache=True, fastmath=False)


@_jit
def _is_intersect(p1x, p1y, p2x, p2y, p3x, p3y, p4x, p4y):
    det = (p4y - p3y) * (p2x - p1x) - (p4x - p3x) * (p2y - p1y)
    if abs(det) < MINVAL:
        return False
    a = ((p4x - p3x) * (p1y - p3y) - (p4y - p3y) * (p1x - p3x)) / det
    b = ((p2x - p1x) * (p1y - p3y) - (p2y - p1y) * (p1x - p3x)) / det
    return 0.0 <= a <= 1.0 and 0.0 <= b <= 1.0


@_jit
def _length_circle(p0x, p0y, p1x, p1y, ind, rad):
    n0 = math.sqrt(p0x * p0x + p0y * p0y)
    n1 = math.sqrt(p1x * p1x + p1y * p1y)
    c = (p0x * p1x + p0y * p1y) / (n0 * n1)
    angle = math.acos(min(1.0, max(-1.0, c)))
    cross = p0y * p1x - p0x * p1y
    if (cross > 0 and ind) or (cross < 0 and not ind):
        angle = 2 * math.pi - angle
    return rad * angle


@_jit
def _wrap_circle(d, sd0, sd1, has_side, rad, pnt):
    """MuJoCo wrap_circle: 2-D tangent points in pnt[4]; returns arc length or -1."""
    sqlen0 = d[0] * d[0] + d[1] * d[1]
    sqlen1 = d[2] * d[2] + d[3] * d[3]
    sqrad = rad * rad
    if sqlen0 < sqrad or sqlen1 < sqrad or rad < MINVAL:
        return -1.0
    dx, dy = d[2] - d[0], d[3] - d[1]
    dd = dx * dx + dy * dy
    if dd < MINVAL:
        return -1.0
    a = -(dx * d[0] + dy * d[1]) / dd
    a = min(1.0, max(0.0, a))
    tx, ty = a * dx + d[0], a * dy + d[1]
    if tx * tx + ty * ty > sqrad and (not has_side or sd0 * tx + sd1 * ty >= 0):
        return -1.0
    sqrt0 = math.sqrt(sqlen0 - sqrad)
    sqrt1 = math.sqrt(sqlen1 - sqrad)
    best_good = 0.0
    best = 0
    for i in range(2):
        sgn = 1.0 if i == 0 else -1.0
        s0 = (d[0] * sqrad + sgn * rad * d[1] * sqrt0) / sqlen0
        s1 = (d[1] * sqrad - sgn * rad * d[0] * sqrt0) / sqlen0
        s2 = (d[2] * sqrad - sgn * rad * d[3] * sqrt1) / sqlen1
        s3 = (d[3] * sqrad + sgn * rad * d[2] * sqrt1) / sqlen1
        if has_side:
            mx, my = s0 + s2, s1 + s3
            mn = math.sqrt(mx * mx + my * my)
            if mn < MINVAL:
                mn = 1.0
            good = (mx * sd0 + my * sd1) / mn
        else:
            ex, ey = s0 - s2, s1 - s3
            good = -(ex * ex + ey * ey)
        if _is_intersect(d[0], d[1], s0, s1, d[2], d[3], s2, s3):
            good = -10000.0
        # MuJoCo keeps solution 0 only if strictly better than solution 1
        if i == 0 or not (best_good > good):
            best_good, best = good, i
            pnt[0], pnt[1], pnt[2], pnt[3] = s0, s1, s2, s3
    if _is_intersect(d[0], d[1], pnt[0], pnt[1], d[2], d[3], pnt[2], pnt[3]):
        return -1.0
    return _length_circle(pnt[0], pnt[1], pnt[2], pnt[3], best == 1, rad)


@_jit
def _wrap_inside(d, rad, pnt):
    """MuJoCo wrap_inside: one tangent point (pnt[0:2] = pnt[2:4]); 0 if wrapped, -1 if not."""
    len0 = math.sqrt(d[0] * d[0] + d[1] * d[1])
    len1 = math.sqrt(d[2] * d[2] + d[3] * d[3])
    dx, dy = d[2] - d[0], d[3] - d[1]
    dd = dx * dx + dy * dy
    if len0 <= rad or len1 <= rad or rad < MINVAL or len0 < MINVAL or len1 < MINVAL:
        return -1.0
    if dd > MINVAL:
        a = -(dx * d[0] + dy * d[1]) / dd
        if 0 < a < 1:
            tx, ty = d[0] + a * dx, d[1] + a * dy
            if math.sqrt(tx * tx + ty * ty) <= rad:
                return -1.0
    mx, my = 0.5 * (d[0] + d[2]), 0.5 * (d[1] + d[3])
    mn = math.sqrt(mx * mx + my * my)
    if mn < MINVAL:
        mn = MINVAL
    pnt[0], pnt[1] = rad * mx / mn, rad * my / mn
    pnt[2], pnt[3] = pnt[0], pnt[1]
    A, B = rad / len0, rad / len1
    cos_g = (len0 * len0 + len1 * len1 - dd) / (2 * len0 * len1)
    if cos_g < -1 + MINVAL:
        return -1.0
    if cos_g > 1 - MINVAL:
        return 0.0
    G = math.acos(cos_g)
    z = 1 - 1e-7
    f = math.asin(A * z) + math.asin(B * z) - 2 * math.asin(z) + G
    if f > 0:
        return 0.0
    it = 0
    while it < 20 and abs(f) > 1e-6:
        df = (A / max(MINVAL, math.sqrt(1 - z * z * A * A)) + B / max(MINVAL, math.sqrt(1 - z * z * B * B))
              - 2 / max(MINVAL, math.sqrt(1 - z * z)))
        if df > -MINVAL:
            return 0.0
        z1 = z - f / df
        if z1 > z:
            return 0.0
        z = z1
        f = math.asin(A * z) + math.asin(B * z) - 2 * math.asin(z) + G
        if f > 1e-6:
            return 0.0
        it += 1
    if it >= 20:
        return 0.0
    if d[0] * d[3] - d[1] * d[2] > 0:
        vx, vy, ang = d[0], d[1], math.asin(z) - math.asin(A * z)
    else:
        vx, vy, ang = d[2], d[3], math.asin(z) - math.asin(B * z)
    vn = math.sqrt(vx * vx + vy * vy)
    vx, vy = vx / vn, vy / vn
    pnt[0] = rad * (math.cos(ang) * vx - math.sin(ang) * vy)
    pnt[1] = rad * (math.sin(ang) * vx + math.cos(ang) * vy)
    pnt[2], pnt[3] = pnt[0], pnt[1]
    return 0.0


@_jit
def _cross(a, b, out):
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@_jit
def _to_local(R, c, x, out):
    """out = R^T (x - c)."""
    d0, d1, d2 = x[0] - c[0], x[1] - c[1], x[2] - c[2]
    for i in range(3):
        out[i] = R[0, i] * d0 + R[1, i] * d1 + R[2, i] * d2


@_jit
def wrap(x0, x1, center, R, radius, cylinder, side, has_side, w0, w1, work):
    """MuJoCo mju_wrap: world tangent points in w0, w1; returns wrapped length or -1.

    `work` is scratch space of shape (10, 4).
    """
    p0, p1, s, axis0, axis1, normal, r0, r1 = work[0, :3], work[1, :3], work[2, :3], work[3, :3], work[4, :3], work[5, :3], work[6, :3], work[7, :3]
    d, pnt = work[8], work[9]
    _to_local(R, center, x0, p0)
    _to_local(R, center, x1, p1)
    n0 = math.sqrt(p0[0] * p0[0] + p0[1] * p0[1] + p0[2] * p0[2])
    if n0 < MINVAL or math.sqrt(p1[0] * p1[0] + p1[1] * p1[1] + p1[2] * p1[2]) < MINVAL:
        return -1.0
    if cylinder:
        axis0[0], axis0[1], axis0[2] = 1.0, 0.0, 0.0
        axis1[0], axis1[1], axis1[2] = 0.0, 1.0, 0.0
    else:
        for i in range(3):
            axis0[i] = p0[i] / n0
        _cross(p0, p1, normal)
        nrm = math.sqrt(normal[0] ** 2 + normal[1] ** 2 + normal[2] ** 2)
        if nrm < MINVAL:  # p0 parallel to p1: another normal
            i = 0
            if abs(axis0[1]) > abs(axis0[0]) and abs(axis0[1]) > abs(axis0[2]):
                i = 1
            if abs(axis0[2]) > abs(axis0[0]) and abs(axis0[2]) > abs(axis0[1]):
                i = 2
            alt = r0  # scratch
            alt[0], alt[1], alt[2] = 1.0, 1.0, 1.0
            alt[i] = 0.0
            _cross(axis0, alt, normal)
            nrm = math.sqrt(normal[0] ** 2 + normal[1] ** 2 + normal[2] ** 2)
        for i in range(3):
            normal[i] /= nrm
        _cross(normal, axis0, axis1)
        n1 = math.sqrt(axis1[0] ** 2 + axis1[1] ** 2 + axis1[2] ** 2)
        for i in range(3):
            axis1[i] /= n1
    d[0] = p0[0] * axis0[0] + p0[1] * axis0[1] + p0[2] * axis0[2]
    d[1] = p0[0] * axis1[0] + p0[1] * axis1[1] + p0[2] * axis1[2]
    d[2] = p1[0] * axis0[0] + p1[1] * axis0[1] + p1[2] * axis0[2]
    d[3] = p1[0] * axis1[0] + p1[1] * axis1[1] + p1[2] * axis1[2]
    sd0 = sd1 = 0.0
    inside = False
    if has_side:
        _to_local(R, center, side, s)
        sd0 = s[0] * axis0[0] + s[1] * axis0[1] + s[2] * axis0[2]
        sd1 = s[0] * axis1[0] + s[1] * axis1[1] + s[2] * axis1[2]
        sn = math.sqrt(sd0 * sd0 + sd1 * sd1)
        if sn >= radius:
            sd0, sd1 = sd0 * radius / sn, sd1 * radius / sn
        else:
            sd0 = sd1 = 0.0
            inside = True
    if inside:
        wlen = _wrap_inside(d, radius, pnt)
    else:
        wlen = _wrap_circle(d, sd0, sd1, has_side, radius, pnt)
    if wlen < 0:
        return -1.0
    for i in range(3):
        r0[i] = axis0[i] * pnt[0] + axis1[i] * pnt[1]
        r1[i] = axis0[i] * pnt[2] + axis1[i] * pnt[3]
    if cylinder:
        L0 = math.sqrt((p0[0] - r0[0]) ** 2 + (p0[1] - r0[1]) ** 2)
        L1 = math.sqrt((p1[0] - r1[0]) ** 2 + (p1[1] - r1[1]) ** 2)
        total = L0 + wlen + L1
        r0[2] = p0[2] + (p1[2] - p0[2]) * L0 / total
        r1[2] = p0[2] + (p1[2] - p0[2]) * (L0 + wlen) / total
        height = abs(r1[2] - r0[2])
        wlen = math.sqrt(wlen * wlen + height * height)
    for i in range(3):
        w0[i] = R[i, 0] * r0[0] + R[i, 1] * r0[1] + R[i, 2] * r0[2] + center[i]
        w1[i] = R[i, 0] * r1[0] + R[i, 1] * r1[1] + R[i, 2] * r1[2] + center[i]
    return wlen


# ------------------------------------------------------------------------ path kernel
# Written with explicit 3-vector loops: tiny numpy temporaries and BLAS calls would dominate.

@numba.njit(cache=True, inline="always")
def add_pull(m, u0, u1, u2, pa, ba, pb, bb, revolute, moves, axes, axo, grad):
    """grad[m] += u . (J_b - J_a) for points pa (on body ba) and pb (on body bb), unit vector u.

    Revolute column k: moves * a_k . (p x u) - u . (a_k x o_k); prismatic: moves * u . a_k.
    """
    ca0, ca1, ca2 = pa[1] * u2 - pa[2] * u1, pa[2] * u0 - pa[0] * u2, pa[0] * u1 - pa[1] * u0
    cb0, cb1, cb2 = pb[1] * u2 - pb[2] * u1, pb[2] * u0 - pb[0] * u2, pb[0] * u1 - pb[1] * u0
    for k in range(axes.shape[0]):
        if moves[bb, k] == moves[ba, k]:  # the joint moves both points or neither: the terms cancel exactly
            continue
        if revolute[k]:
            base = u0 * axo[k, 0] + u1 * axo[k, 1] + u2 * axo[k, 2]
            ja = axes[k, 0] * ca0 + axes[k, 1] * ca1 + axes[k, 2] * ca2 - base
            jb = axes[k, 0] * cb0 + axes[k, 1] * cb1 + axes[k, 2] * cb2 - base
        else:
            ja = jb = u0 * axes[k, 0] + u1 * axes[k, 1] + u2 * axes[k, 2]
        grad[m, k] += moves[bb, k] * jb - moves[ba, k] * ja


@numba.njit(cache=True, inline="always")
def _add_segment(m, P, a, ba, Q, b, bb, revolute, moves, axes, axo, lengths, grad):
    """Add the straight segment P[a] (body ba) -> Q[b] (body bb) to muscle m."""
    u0, u1, u2 = Q[b, 0] - P[a, 0], Q[b, 1] - P[a, 1], Q[b, 2] - P[a, 2]
    L = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
    lengths[m] += L
    if L < MINVAL:
        return
    add_pull(m, u0 / L, u1 / L, u2 / L, P[a], ba, Q[b], bb, revolute, moves, axes, axo, grad)


@numba.njit(cache=True, inline="always")
def site_positions(R, p, site_body, site_local):
    """World positions (n_sites, 3) of points given in their bodies' frames."""
    n_sites = site_body.shape[0]
    P = np.empty((n_sites, 3))
    for i in range(n_sites):
        b = site_body[i]
        for r in range(3):
            P[i, r] = R[b, r, 0] * site_local[i, 0] + R[b, r, 1] * site_local[i, 1] + R[b, r, 2] * site_local[i, 2] + p[b, r]
    return P


@numba.njit(cache=True, inline="always")
def axis_moments(axes, origins):
    """a_k x o_k for every joint axis (the point-independent part of a revolute Jacobian column)."""
    axo = np.empty((axes.shape[0], 3))
    for k in range(axes.shape[0]):
        _cross(axes[k], origins[k], axo[k])
    return axo


@_jit
def _path_kernel(R, p, axes, origins, revolute, moves, site_body, site_local, st, wr, wr_body, wr_pos, wr_rot,
                 wr_radius, wr_cyl, n_muscles, points_out, wrap_length_out):
    """Lengths and length gradients; with non-empty `points_out` (n_sites + 2 n_wraps, 3) and
    `wrap_length_out` (n_wraps,) also the world site points, the tangent points of every wrap
    (both at its first site where the path misses the surface) and the wrapped arc lengths (-1)."""
    P = site_positions(R, p, site_body, site_local)
    n_sites = site_body.shape[0]
    record = points_out.shape[0] > 0
    axo = axis_moments(axes, origins)
    nc = axes.shape[0]
    lengths = np.zeros(n_muscles)
    grad = np.zeros((n_muscles, nc))
    for h in range(st.shape[0]):
        a, b, m = st[h, 0], st[h, 1], st[h, 2]
        _add_segment(m, P, a, site_body[a], P, b, site_body[b], revolute, moves, axes, axo, lengths, grad)
    T = np.empty((2, 3))
    work = np.empty((10, 4))
    Rw = np.empty((3, 3))
    cw = np.empty(3)
    for h in range(wr.shape[0]):
        a, b, side, m = wr[h, 0], wr[h, 1], wr[h, 2], wr[h, 3]
        gb = wr_body[h]
        for r in range(3):  # wrap pose in world: R_body @ (R_local, p_local) + p_body
            cw[r] = R[gb, r, 0] * wr_pos[h, 0] + R[gb, r, 1] * wr_pos[h, 1] + R[gb, r, 2] * wr_pos[h, 2] + p[gb, r]
            for c in range(3):
                Rw[r, c] = R[gb, r, 0] * wr_rot[h, 0, c] + R[gb, r, 1] * wr_rot[h, 1, c] + R[gb, r, 2] * wr_rot[h, 2, c]
        sp = P[side] if side >= 0 else P[a]
        wlen = wrap(P[a], P[b], cw, Rw, wr_radius[h], wr_cyl[h], sp, side >= 0, T[0], T[1], work)
        if record:
            wrap_length_out[h] = wlen
            for r in range(3):
                points_out[n_sites + 2 * h, r] = T[0, r] if wlen >= 0 else P[a, r]
                points_out[n_sites + 2 * h + 1, r] = T[1, r] if wlen >= 0 else P[a, r]
        if wlen < 0:
            _add_segment(m, P, a, site_body[a], P, b, site_body[b], revolute, moves, axes, axo, lengths, grad)
        else:
            _add_segment(m, P, a, site_body[a], T, 0, gb, revolute, moves, axes, axo, lengths, grad)
            _add_segment(m, T, 1, gb, P, b, site_body[b], revolute, moves, axes, axo, lengths, grad)
            lengths[m] += wlen
    if record:
        points_out[:n_sites] = P
    return lengths, grad


class MusclePaths:
    """Path geometry of all muscles of a ModelSpec on a given set of bodies.

    `bodies` are the names of the bodies whose world poses are supplied to `compute`
    (in that order); `coord_kinds[k]` is "hinge" or "slide" and `coord_moves[b, k]` is 1
    where coordinate k moves body b.
    """

    def __init__(self, spec: ModelSpec, bodies: list[str], coord_kinds: list[str], coord_moves: np.ndarray):
        self.n_muscles = len(spec.muscles)
        body_index = {b: i for i, b in enumerate(bodies)}
        self._revolute = np.array([k == "hinge" for k in coord_kinds], dtype=np.bool_)
        self._moves = np.ascontiguousarray(coord_moves, dtype=float)  # (n_bodies, n_coords)

        used_sites: dict[int, int] = {}

        def site_slot(s: int) -> int:
            return used_sites.setdefault(s, len(used_sites))

        straight, wraps, geoms, routes = [], [], [], []  # straight: (a, b, muscle); wraps: (a, b, side, muscle)
        for m, mus in enumerate(spec.muscles):
            path = mus.path
            route = [("site", site_slot(path[0].index))] if path and path[0].kind == "site" else []
            j = 0
            while j < len(path) - 1:
                a, nxt = path[j], path[j + 1]
                if a.kind != "site":
                    raise ValueError(f"muscle {mus.name}: path element {j} must be a site, got {a.kind}")
                if nxt.kind == "wrap":
                    if j + 2 >= len(path) or path[j + 2].kind != "site":
                        raise ValueError(f"muscle {mus.name}: a wrap must sit between two sites (element {j + 1})")
                    side = -1 if nxt.side_site < 0 else site_slot(nxt.side_site)
                    wraps.append((site_slot(a.index), site_slot(path[j + 2].index), side, m))
                    geoms.append(spec.wraps[nxt.index])
                    route += [("wrap", len(wraps) - 1), ("site", site_slot(path[j + 2].index))]
                    j += 2
                else:
                    straight.append((site_slot(a.index), site_slot(nxt.index), m))
                    route.append(("site", site_slot(nxt.index)))
                    j += 1
            routes.append(tuple(route))
        order = sorted(used_sites, key=used_sites.get)
        self._site_body = np.array([body_index[spec.sites[s].body] for s in order], dtype=np.int64)
        self._site_local = np.array([spec.sites[s].pos for s in order], dtype=float)
        self._st = np.array(straight, dtype=np.int64).reshape(-1, 3)
        self._wr = np.array(wraps, dtype=np.int64).reshape(-1, 4)
        self._wr_body = np.array([body_index[g.body] for g in geoms], dtype=np.int64)
        self._wr_pos = np.array([g.pos for g in geoms], dtype=float).reshape(-1, 3)
        self._wr_rot = np.array([quat_matrix(g.quat) for g in geoms], dtype=float).reshape(-1, 3, 3)
        self._wr_radius = np.array([g.radius for g in geoms], dtype=float)
        self._wr_cyl = np.array([g.kind == "cylinder" for g in geoms], dtype=np.bool_)
        self.layout = PathLayout(tuple(routes), self._site_body, self._site_local, self._wr_body, self._wr_pos,
                                 self._wr_rot, self._wr_radius, self._wr_cyl)
        self._no_points, self._no_wrap_lengths = np.empty((0, 3)), np.empty(0)  # compute() records no points

    def bodies_used(self) -> set[int]:
        """Indices of the bodies whose poses `compute` reads."""
        return {int(b) for b in self._site_body} | {int(b) for b in self._wr_body}

    def compute(self, R_body: np.ndarray, p_body: np.ndarray, axes: np.ndarray, origins: np.ndarray, v: np.ndarray | None = None) -> PathState:
        """Lengths and moment arms from body poses (R (nb, 3, 3), p (nb, 3)) and coordinate axes.

        axes, origins: (n_coords, 3) world joint axes and points on them (origins unused for
        slides). With `v` (generalized velocities), lengthening velocities are returned too.
        """
        lengths, grad = _path_kernel(
            np.ascontiguousarray(R_body), np.ascontiguousarray(p_body), axes, origins, self._revolute, self._moves,
            self._site_body, self._site_local, self._st, self._wr, self._wr_body, self._wr_pos, self._wr_rot,
            self._wr_radius, self._wr_cyl, self.n_muscles, self._no_points, self._no_wrap_lengths,
        )
        state = PathState(lengths=lengths, moment_arms=-grad)
        if v is not None:
            state.velocities = grad @ np.asarray(v, dtype=float)
        return state

    def points(self, R_body: np.ndarray, p_body: np.ndarray) -> PathPoints:
        """World points of every path (sites and wrap tangent points) from body poses."""
        n_sites, n_wraps = len(self._site_body), len(self._wr)
        points, wrap_lengths = np.empty((n_sites + 2 * n_wraps, 3)), np.empty(n_wraps)
        no_coords = np.empty((0, 3))
        _path_kernel(
            np.ascontiguousarray(R_body), np.ascontiguousarray(p_body), no_coords, no_coords, self._revolute[:0],
            np.ascontiguousarray(self._moves[:, :0]), self._site_body, self._site_local, self._st, self._wr, self._wr_body,
            self._wr_pos, self._wr_rot, self._wr_radius, self._wr_cyl, self.n_muscles, points, wrap_lengths,
        )
        return PathPoints(points[:n_sites], points[n_sites:].reshape(n_wraps, 2, 3), wrap_lengths)
