"""Muscle path kinematics: lengths, lengthening velocities and moment arms, vectorised.

A path is a chain of sites; between two sites it may wrap over a sphere or an infinite
cylinder, optionally steered by a side-site, exactly as MuJoCo's spatial tendons
(`mju_wrap`, `mj_tendon`): tangent points are found in the plane of the wrap (sphere:
the plane through the centre and both end points; cylinder: the plane normal to its
axis, the height interpolated along the path), the inside-wrap variant is used when the
side-site lies inside the surface. The geometry is our own, computed from the poses of
the Drake plant's bodies; MuJoCo is only the test oracle.

Moment arms are `-dL/dq`. The length gradient is the sum over straight segments of the
unit segment direction dotted with the difference of the end-point Jacobians, where
wrap tangent points move with the wrap surface's body; for a taut (shortest) path the
wrapped arc contributes nothing to first order.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse

from trunk_drake.model.spec import ModelSpec

MINVAL = 1e-15  # MuJoCo's mjMINVAL


@dataclass
class PathState:
    """Muscle-tendon lengths (m), lengthening velocities (m/s) and moment arms (m or m/rad)."""

    lengths: np.ndarray  # (n_muscles,)
    moment_arms: np.ndarray  # (n_muscles, n_coordinates), = -dL/dq
    velocities: np.ndarray | None = None  # (n_muscles,), = -moment_arms @ v


def _quat_matrix(q: np.ndarray) -> np.ndarray:
    w, x, y, z = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def _normalize(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = np.sqrt((v * v).sum(axis=-1))
    return v / np.where(n < MINVAL, 1.0, n)[..., None], n


def _segments_intersect(p1x, p1y, p2x, p2y, p3x, p3y, p4x, p4y) -> np.ndarray:
    """MuJoCo's is_intersect for 2-D segments p1-p2 and p3-p4, vectorised over components."""
    det = (p4y - p3y) * (p2x - p1x) - (p4x - p3x) * (p2y - p1y)
    ok = np.abs(det) >= MINVAL
    sdet = np.where(ok, det, 1.0)
    a = ((p4x - p3x) * (p1y - p3y) - (p4y - p3y) * (p1x - p3x)) / sdet
    b = ((p2x - p1x) * (p1y - p3y) - (p2y - p1y) * (p1x - p3x)) / sdet
    return ok & (a >= 0) & (a <= 1) & (b >= 0) & (b <= 1)


def _wrap_circle(d0, d1, sd, has_side, rad):
    """2-D wrap of segment d0-d1 around a circle of radius rad at the origin (MuJoCo wrap_circle).

    Returns tangent points (n, 2) x 2, arc length (n,) and a mask of wrapped cases. Both
    candidate solutions are computed at once (leading axis of length 2).
    """
    x0, y0, x1, y1 = d0[:, 0], d0[:, 1], d1[:, 0], d1[:, 1]
    sqlen0 = x0 * x0 + y0 * y0
    sqlen1 = x1 * x1 + y1 * y1
    sqrad = rad * rad
    dx, dy = x1 - x0, y1 - y0
    dd = dx * dx + dy * dy
    valid = (sqlen0 >= sqrad) & (sqlen1 >= sqrad) & (rad >= MINVAL) & (dd >= MINVAL)
    a = np.clip(-(dx * x0 + dy * y0) / np.where(dd < MINVAL, 1.0, dd), 0.0, 1.0)
    nx, ny = a * dx + x0, a * dy + y0
    clear = (nx * nx + ny * ny > sqrad) & (~has_side | (sd[:, 0] * nx + sd[:, 1] * ny >= 0))
    valid &= ~clear

    k0 = rad * np.sqrt(np.maximum(sqlen0 - sqrad, 0.0)) / np.where(valid, sqlen0, 1.0)
    k1 = rad * np.sqrt(np.maximum(sqlen1 - sqrad, 0.0)) / np.where(valid, sqlen1, 1.0)
    c0 = sqrad / np.where(valid, sqlen0, 1.0)
    c1 = sqrad / np.where(valid, sqlen1, 1.0)
    sgn = np.array([[1.0], [-1.0]])
    t0x, t0y = x0 * c0 + sgn * k0 * y0, y0 * c0 - sgn * k0 * x0  # (2, n)
    t1x, t1y = x1 * c1 - sgn * k1 * y1, y1 * c1 + sgn * k1 * x1
    mx, my = t0x + t1x, t0y + t1y
    mn = np.sqrt(mx * mx + my * my)
    mn = np.where(mn < MINVAL, 1.0, mn)
    ex, ey = t0x - t1x, t0y - t1y
    good = np.where(has_side, (mx * sd[:, 0] + my * sd[:, 1]) / mn, -(ex * ex + ey * ey))
    good = np.where(_segments_intersect(x0, y0, t0x, t0y, x1, y1, t1x, t1y), -10000.0, good)
    second = ~(good[0] > good[1])
    pick = second.astype(int)
    cols = np.arange(len(rad))
    t0x, t0y, t1x, t1y = t0x[pick, cols], t0y[pick, cols], t1x[pick, cols], t1y[pick, cols]
    valid &= ~_segments_intersect(x0, y0, t0x, t0y, x1, y1, t1x, t1y)

    n0 = np.sqrt(t0x * t0x + t0y * t0y)
    n1 = np.sqrt(t1x * t1x + t1y * t1y)
    cosang = (t0x * t1x + t0y * t1y) / np.where(n0 * n1 < MINVAL, 1.0, n0 * n1)
    angle = np.arccos(np.clip(cosang, -1.0, 1.0))
    cross = t0y * t1x - t0x * t1y
    flip = ((cross > 0) & second) | ((cross < 0) & ~second)
    angle = np.where(flip, 2 * np.pi - angle, angle)
    return np.stack([t0x, t0y], axis=1), np.stack([t1x, t1y], axis=1), rad * angle, valid


def _wrap_inside(d0, d1, rad):
    """2-D inside wrap (MuJoCo wrap_inside): one tangent point, zero arc. Rarely used."""
    n = d0.shape[0]
    pnt = np.zeros((n, 2))
    valid = np.zeros(n, dtype=bool)
    for i in range(n):  # side-sites inside a wrap surface are rare; a scalar Newton is enough
        pnt[i], valid[i] = _wrap_inside_one(d0[i], d1[i], rad[i])
    return pnt, valid


def _wrap_inside_one(d0, d1, rad):
    len0, len1 = np.linalg.norm(d0), np.linalg.norm(d1)
    dif = d1 - d0
    dd = dif @ dif
    if len0 <= rad or len1 <= rad or rad < MINVAL or len0 < MINVAL or len1 < MINVAL:
        return np.zeros(2), False
    if dd > MINVAL:
        a = -(dif @ d0) / dd
        if 0 < a < 1 and np.linalg.norm(d0 + a * dif) <= rad:
            return np.zeros(2), False
    mid = 0.5 * (d0 + d1)
    fallback = mid / max(np.linalg.norm(mid), MINVAL) * rad
    A, B = rad / len0, rad / len1
    cos_g = (len0 * len0 + len1 * len1 - dd) / (2 * len0 * len1)
    if cos_g < -1 + MINVAL:
        return np.zeros(2), False
    if cos_g > 1 - MINVAL:
        return fallback, True
    G = np.arccos(cos_g)
    z = 1 - 1e-7
    f = np.arcsin(A * z) + np.arcsin(B * z) - 2 * np.arcsin(z) + G
    if f > 0:
        return fallback, True
    for _ in range(20):
        if abs(f) <= 1e-6:
            break
        df = A / max(MINVAL, np.sqrt(1 - z * z * A * A)) + B / max(MINVAL, np.sqrt(1 - z * z * B * B)) - 2 / max(MINVAL, np.sqrt(1 - z * z))
        if df > -MINVAL:
            return fallback, True
        z1 = z - f / df
        if z1 > z:
            return fallback, True
        z = z1
        f = np.arcsin(A * z) + np.arcsin(B * z) - 2 * np.arcsin(z) + G
        if f > 1e-6:
            return fallback, True
    else:
        if abs(f) > 1e-6:
            return fallback, True
    if d0[0] * d1[1] - d0[1] * d1[0] > 0:
        vec, ang = d0, np.arcsin(z) - np.arcsin(A * z)
    else:
        vec, ang = d1, np.arcsin(z) - np.arcsin(B * z)
    vec = vec / np.linalg.norm(vec)
    return rad * np.array([np.cos(ang) * vec[0] - np.sin(ang) * vec[1], np.sin(ang) * vec[0] + np.cos(ang) * vec[1]]), True


def wrap_points(x0, x1, center, R, radius, cylinder, side, has_side):
    """Vectorised MuJoCo `mju_wrap` for n wrap instances.

    x0, x1: (n, 3) world end points; center (n, 3), R (n, 3, 3) wrap pose; radius (n,);
    cylinder (n,) bool; side (n, 3) side-site positions (ignored where not has_side).
    Returns world tangent points t0, t1 (n, 3), wrapped length (n,), and the wrapped mask.
    """
    p0, p1, s = np.einsum("nji,knj->kni", R, np.stack([x0, x1, side]) - center)  # local frame
    a0, n_p0 = _normalize(p0)
    normal, nrm = _normalize(_cross(p0, p1))
    # sphere with p0 parallel to p1: MuJoCo picks another normal
    parallel = nrm < MINVAL
    if np.any(parallel & ~cylinder):
        absa = np.abs(a0)
        idx = np.where((absa[:, 1] > absa[:, 0]) & (absa[:, 1] > absa[:, 2]), 1, 0)
        idx = np.where((absa[:, 2] > absa[:, 0]) & (absa[:, 2] > absa[:, 1]), 2, idx)
        alt = np.ones_like(a0)
        alt[np.arange(len(idx)), idx] = 0.0
        alt_normal, _ = _normalize(_cross(a0, alt))
        normal = np.where(parallel[:, None], alt_normal, normal)
    a1, _ = _normalize(_cross(normal, a0))
    # 2-D frame of the wrap plane: (axis0, axis1) rows; cylinders use local x, y
    basis = np.where(cylinder[:, None, None], np.eye(3)[:2], np.stack([a0, a1], axis=1))  # (n, 2, 3)
    d0, d1, sd = np.einsum("nij,knj->kni", basis, np.stack([p0, p1, s]))
    sd_dir, sd_norm = _normalize(sd)
    outside = sd_norm >= radius
    sd = np.where(outside[:, None], sd_dir * radius[:, None], 0.0)
    inside = has_side & ~outside

    t0, t1, wlen, valid = _wrap_circle(d0, d1, sd, has_side, radius)
    if np.any(inside):
        pin, vin = _wrap_inside(d0[inside], d1[inside], radius[inside])
        t0[inside], t1[inside], wlen[inside], valid[inside] = pin, pin, 0.0, vin
    valid &= (n_p0 >= MINVAL) & (np.linalg.norm(p1, axis=1) >= MINVAL)

    r0, r1 = np.einsum("nij,kni->knj", basis, np.stack([t0, t1]))
    if np.any(cylinder):
        L0 = np.hypot(p0[:, 0] - r0[:, 0], p0[:, 1] - r0[:, 1])
        L1 = np.hypot(p1[:, 0] - r1[:, 0], p1[:, 1] - r1[:, 1])
        total = np.where(valid, L0 + wlen + L1, 1.0)
        z0 = p0[:, 2] + (p1[:, 2] - p0[:, 2]) * L0 / total
        z1 = p0[:, 2] + (p1[:, 2] - p0[:, 2]) * (L0 + wlen) / total
        r0[:, 2] = np.where(cylinder, z0, r0[:, 2])
        r1[:, 2] = np.where(cylinder, z1, r1[:, 2])
        wlen = np.where(cylinder, np.hypot(wlen, z1 - z0), wlen)
    w0, w1 = np.einsum("nij,knj->kni", R, np.stack([r0, r1])) + center
    return w0, w1, wlen, valid


class MusclePaths:
    """Vectorised path geometry of all muscles of a ModelSpec on a given set of bodies.

    `bodies` are the names of the bodies whose world poses are supplied to `compute`
    (in that order); `coord_kinds[k]` is "hinge" or "slide" and `coord_moves[b, k]` is 1
    where coordinate k moves body b.
    """

    def __init__(self, spec: ModelSpec, bodies: list[str], coord_kinds: list[str], coord_moves: np.ndarray):
        self.n_muscles = len(spec.muscles)
        self.n_coords = len(coord_kinds)
        body_index = {b: i for i, b in enumerate(bodies)}
        self._revolute = np.array([k == "hinge" for k in coord_kinds])
        self._moves = np.asarray(coord_moves, dtype=float)  # (n_bodies, n_coords)

        used_sites: dict[int, int] = {}

        def site_slot(s: int) -> int:
            if s not in used_sites:
                used_sites[s] = len(used_sites)
            return used_sites[s]

        straight, wraps = [], []  # straight: (site_a, site_b, muscle); wraps: (a, b, wrap, side, muscle)
        for m, mus in enumerate(spec.muscles):
            path = mus.path
            j = 0
            while j < len(path) - 1:
                a, nxt = path[j], path[j + 1]
                if a.kind != "site":
                    raise ValueError(f"muscle {mus.name}: path element {j} must be a site, got {a.kind}")
                if nxt.kind == "wrap":
                    if j + 2 >= len(path) or path[j + 2].kind != "site":
                        raise ValueError(f"muscle {mus.name}: a wrap must sit between two sites (element {j + 1})")
                    side = -1 if nxt.side_site < 0 else site_slot(nxt.side_site)
                    wraps.append((site_slot(a.index), site_slot(path[j + 2].index), nxt.index, side, m))
                    j += 2
                else:
                    straight.append((site_slot(a.index), site_slot(nxt.index), m))
                    j += 1
        order = sorted(used_sites, key=used_sites.get)
        self._site_body = np.array([body_index[spec.sites[s].body] for s in order])
        self._site_local = np.array([spec.sites[s].pos for s in order])
        st = np.array(straight, dtype=int).reshape(-1, 3)
        self._st_a, self._st_b, self._st_m = st[:, 0], st[:, 1], st[:, 2]
        wr = np.array(wraps, dtype=int).reshape(-1, 5)
        self._wr_a, self._wr_b, self._wr_m = wr[:, 0], wr[:, 1], wr[:, 4]
        self._wr_has_side = wr[:, 3] >= 0
        self._wr_side = np.where(self._wr_has_side, wr[:, 3], 0)
        geoms = [spec.wraps[w] for w in wr[:, 2]]
        self._wr_body = np.array([body_index[g.body] for g in geoms], dtype=int)
        self._wr_pos = np.array([g.pos for g in geoms]).reshape(-1, 3)
        self._wr_rot = np.array([_quat_matrix(g.quat) for g in geoms]).reshape(-1, 3, 3)
        self._wr_radius = np.array([g.radius for g in geoms], dtype=float)
        self._wr_cyl = np.array([g.kind == "cylinder" for g in geoms], dtype=bool)

        # straight pieces in a fixed order: site->site hops, then per wrap hop
        # site->tangent, tangent->site (used when wrapped) and site->site (when not)
        sb, wb = self._site_body, self._wr_body
        self._seg_start_body = np.concatenate([sb[self._st_a], sb[self._wr_a], wb, sb[self._wr_a]])
        self._seg_end_body = np.concatenate([sb[self._st_b], wb, sb[self._wr_b], sb[self._wr_b]])
        seg_muscle = np.concatenate([self._st_m, self._wr_m, self._wr_m, self._wr_m])
        self._seg_weight = np.ones(len(seg_muscle))
        self._incidence = sparse.csr_matrix(
            (np.ones(len(seg_muscle)), (seg_muscle, np.arange(len(seg_muscle)))), shape=(self.n_muscles, len(seg_muscle))
        )

    def compute(self, R_body: np.ndarray, p_body: np.ndarray, axes: np.ndarray, origins: np.ndarray, v: np.ndarray | None = None) -> PathState:
        """Lengths and moment arms from body poses (R (nb, 3, 3), p (nb, 3)) and coordinate axes.

        axes, origins: (n_coords, 3) world joint axes and points on them (origins unused for
        slides). With `v` (generalized velocities), lengthening velocities are returned too.
        """
        P = (R_body[self._site_body] @ self._site_local[:, :, None])[:, :, 0] + p_body[self._site_body]
        Rwb = R_body[self._wr_body]
        Rw = Rwb @ self._wr_rot
        cw = (Rwb @ self._wr_pos[:, :, None])[:, :, 0] + p_body[self._wr_body]
        x0, x1 = P[self._wr_a], P[self._wr_b]
        t0, t1, wlen, wrapped = wrap_points(x0, x1, cw, Rw, self._wr_radius, self._wr_cyl, P[self._wr_side], self._wr_has_side)

        # all straight pieces, in the fixed order of self._seg_*: sites, site->t0, t1->site, site->site
        starts = np.concatenate([P[self._st_a], x0, t1, x0])
        ends = np.concatenate([P[self._st_b], t0, x1, x1])
        n_st = len(self._st_m)
        weight = self._seg_weight.copy()
        nw = len(self._wr_m)
        weight[n_st:n_st + nw] = wrapped
        weight[n_st + nw:n_st + 2 * nw] = wrapped
        weight[n_st + 2 * nw:] = ~wrapped

        u, seglen = _normalize(ends - starts)
        lengths = self._incidence @ (weight * seglen)
        lengths += np.bincount(self._wr_m, weights=np.where(wrapped, wlen, 0.0), minlength=self.n_muscles)

        # d(length)/dq = u . (J_end - J_start).  Column k of the Jacobian of point p on body b:
        #   revolute: moves[b, k] * a_k x (p - o_k);  prismatic: moves[b, k] * a_k.
        # u . (a x (p - o)) = a . (p x u) - u . (a x o)
        lin = u @ axes.T
        u_axo = u @ _cross(axes, origins).T
        def column_terms(p):
            rot = _cross(p, u) @ axes.T - u_axo
            return np.where(self._revolute, rot, lin)
        dl = self._moves[self._seg_end_body] * column_terms(ends) - self._moves[self._seg_start_body] * column_terms(starts)
        grad = self._incidence @ (dl * weight[:, None])
        state = PathState(lengths=lengths, moment_arms=-grad)
        if v is not None:
            state.velocities = grad @ np.asarray(v, dtype=float)
        return state


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of (n, 3) arrays (cheaper than np.cross for small n)."""
    return np.stack(
        [a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1], a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2], a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]],
        axis=1,
    )
