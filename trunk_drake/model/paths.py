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
    n = np.sqrt(np.einsum("...i,...i->...", v, v))
    return v / np.where(n < MINVAL, 1.0, n)[..., None], n


def _segments_intersect(p1, p2, p3, p4) -> np.ndarray:
    """MuJoCo's is_intersect for 2-D segments p1-p2 and p3-p4, vectorised (arrays (..., 2))."""
    det = (p4[..., 1] - p3[..., 1]) * (p2[..., 0] - p1[..., 0]) - (p4[..., 0] - p3[..., 0]) * (p2[..., 1] - p1[..., 1])
    ok = np.abs(det) >= MINVAL
    sdet = np.where(ok, det, 1.0)
    a = ((p4[..., 0] - p3[..., 0]) * (p1[..., 1] - p3[..., 1]) - (p4[..., 1] - p3[..., 1]) * (p1[..., 0] - p3[..., 0])) / sdet
    b = ((p2[..., 0] - p1[..., 0]) * (p1[..., 1] - p3[..., 1]) - (p2[..., 1] - p1[..., 1]) * (p1[..., 0] - p3[..., 0])) / sdet
    return ok & (a >= 0) & (a <= 1) & (b >= 0) & (b <= 1)


def _wrap_circle(d0, d1, sd, has_side, rad):
    """2-D wrap of segment d0-d1 around a circle of radius rad at the origin (MuJoCo wrap_circle).

    Returns tangent points (n, 2) x 2, arc length (n,) and a mask of wrapped cases.
    """
    sqlen0 = np.einsum("ij,ij->i", d0, d0)
    sqlen1 = np.einsum("ij,ij->i", d1, d1)
    sqrad = rad * rad
    dif = d1 - d0
    dd = np.einsum("ij,ij->i", dif, dif)
    valid = (sqlen0 >= sqrad) & (sqlen1 >= sqrad) & (rad >= MINVAL) & (dd >= MINVAL)
    a = np.clip(-np.einsum("ij,ij->i", dif, d0) / np.where(dd < MINVAL, 1.0, dd), 0.0, 1.0)
    near = a[:, None] * dif + d0
    clear = (np.einsum("ij,ij->i", near, near) > sqrad) & (~has_side | (np.einsum("ij,ij->i", sd, near) >= 0))
    valid &= ~clear

    sqrt0 = np.sqrt(np.maximum(sqlen0 - sqrad, 0.0))
    sqrt1 = np.sqrt(np.maximum(sqlen1 - sqrad, 0.0))
    s0 = np.where(valid, sqlen0, 1.0)
    s1 = np.where(valid, sqlen1, 1.0)
    sols, goods = [], []
    for sgn in (1.0, -1.0):
        t0 = np.stack([(d0[:, 0] * sqrad + sgn * rad * d0[:, 1] * sqrt0) / s0, (d0[:, 1] * sqrad - sgn * rad * d0[:, 0] * sqrt0) / s0], axis=1)
        t1 = np.stack([(d1[:, 0] * sqrad - sgn * rad * d1[:, 1] * sqrt1) / s1, (d1[:, 1] * sqrad + sgn * rad * d1[:, 0] * sqrt1) / s1], axis=1)
        mid, _ = _normalize(t0 + t1)
        diff = t0 - t1
        good = np.where(has_side, np.einsum("ij,ij->i", mid, sd), -np.einsum("ij,ij->i", diff, diff))
        good = np.where(_segments_intersect(d0, t0, d1, t1), -10000.0, good)
        sols.append((t0, t1))
        goods.append(good)
    second = ~(goods[0] > goods[1])
    t0 = np.where(second[:, None], sols[1][0], sols[0][0])
    t1 = np.where(second[:, None], sols[1][1], sols[0][1])
    valid &= ~_segments_intersect(d0, t0, d1, t1)

    n0, _ = _normalize(t0)
    n1, _ = _normalize(t1)
    angle = np.arccos(np.clip(np.einsum("ij,ij->i", n0, n1), -1.0, 1.0))
    cross = t0[:, 1] * t1[:, 0] - t0[:, 0] * t1[:, 1]
    flip = ((cross > 0) & second) | ((cross < 0) & ~second)
    angle = np.where(flip, 2 * np.pi - angle, angle)
    return t0, t1, rad * angle, valid


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
    p0 = np.einsum("nji,nj->ni", R, x0 - center)
    p1 = np.einsum("nji,nj->ni", R, x1 - center)
    a0, n_p0 = _normalize(p0)
    normal, nrm = _normalize(np.cross(p0, p1))
    # sphere with p0 parallel to p1: MuJoCo picks another normal
    parallel = nrm < MINVAL
    if np.any(parallel & ~cylinder):
        absa = np.abs(a0)
        idx = np.where((absa[:, 1] > absa[:, 0]) & (absa[:, 1] > absa[:, 2]), 1, 0)
        idx = np.where((absa[:, 2] > absa[:, 0]) & (absa[:, 2] > absa[:, 1]), 2, idx)
        alt = np.ones_like(a0)
        alt[np.arange(len(idx)), idx] = 0.0
        alt_normal, _ = _normalize(np.cross(a0, alt))
        normal = np.where(parallel[:, None], alt_normal, normal)
    a1, _ = _normalize(np.cross(normal, a0))
    ex = np.broadcast_to(np.array([1.0, 0.0, 0.0]), a0.shape)
    ey = np.broadcast_to(np.array([0.0, 1.0, 0.0]), a0.shape)
    axis0 = np.where(cylinder[:, None], ex, a0)
    axis1 = np.where(cylinder[:, None], ey, a1)

    d0 = np.stack([np.einsum("ij,ij->i", p0, axis0), np.einsum("ij,ij->i", p0, axis1)], axis=1)
    d1 = np.stack([np.einsum("ij,ij->i", p1, axis0), np.einsum("ij,ij->i", p1, axis1)], axis=1)
    s = np.einsum("nji,nj->ni", R, side - center)
    sd = np.stack([np.einsum("ij,ij->i", s, axis0), np.einsum("ij,ij->i", s, axis1)], axis=1)
    sd_dir, sd_norm = _normalize(sd)
    outside = sd_norm >= radius
    sd = np.where(outside[:, None], sd_dir * radius[:, None], 0.0)
    inside = has_side & ~outside

    t0, t1, wlen, valid = _wrap_circle(d0, d1, sd, has_side, radius)
    if np.any(inside):
        pin, vin = _wrap_inside(d0[inside], d1[inside], radius[inside])
        t0[inside], t1[inside], wlen[inside], valid[inside] = pin, pin, 0.0, vin
    valid &= (n_p0 >= MINVAL) & (np.linalg.norm(p1, axis=1) >= MINVAL)

    r0 = axis0 * t0[:, :1] + axis1 * t0[:, 1:]
    r1 = axis0 * t1[:, :1] + axis1 * t1[:, 1:]
    if np.any(cylinder):
        L0 = np.hypot(p0[:, 0] - r0[:, 0], p0[:, 1] - r0[:, 1])
        L1 = np.hypot(p1[:, 0] - r1[:, 0], p1[:, 1] - r1[:, 1])
        total = np.where(valid, L0 + wlen + L1, 1.0)
        z0 = p0[:, 2] + (p1[:, 2] - p0[:, 2]) * L0 / total
        z1 = p0[:, 2] + (p1[:, 2] - p0[:, 2]) * (L0 + wlen) / total
        r0[:, 2] = np.where(cylinder, z0, r0[:, 2])
        r1[:, 2] = np.where(cylinder, z1, r1[:, 2])
        wlen = np.where(cylinder, np.hypot(wlen, z1 - z0), wlen)
    w0 = np.einsum("nij,nj->ni", R, r0) + center
    w1 = np.einsum("nij,nj->ni", R, r1) + center
    return w0, w1, wlen, valid


class MusclePaths:
    """Vectorised path geometry of all muscles of a ModelSpec on a given set of bodies.

    `bodies` are the names of the bodies whose world poses are supplied to `compute`
    (in that order); `coord_bodies[k]` lists, for coordinate k, the indices into `bodies`
    that the coordinate moves.
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

    def compute(self, R_body: np.ndarray, p_body: np.ndarray, axes: np.ndarray, origins: np.ndarray, v: np.ndarray | None = None) -> PathState:
        """Lengths and moment arms from body poses (R (nb, 3, 3), p (nb, 3)) and coordinate axes.

        axes, origins: (n_coords, 3) world joint axes and points on them (origins unused for
        slides). With `v` (generalized velocities), lengthening velocities are returned too.
        """
        P = np.einsum("nij,nj->ni", R_body[self._site_body], self._site_local) + p_body[self._site_body]
        nw = len(self._wr_m)
        # wrap instances
        Rw = np.einsum("nij,njk->nik", R_body[self._wr_body], self._wr_rot)
        cw = np.einsum("nij,nj->ni", R_body[self._wr_body], self._wr_pos) + p_body[self._wr_body]
        x0, x1 = P[self._wr_a], P[self._wr_b]
        t0, t1, wlen, wrapped = wrap_points(x0, x1, cw, Rw, self._wr_radius, self._wr_cyl, P[self._wr_side], self._wr_has_side)

        # all straight pieces: (start point, start body, end point, end body, muscle)
        sb, wb = self._site_body, self._wr_body
        starts = np.concatenate([P[self._st_a], x0, t1, x0])
        ends = np.concatenate([P[self._st_b], t0, x1, x1])
        start_body = np.concatenate([sb[self._st_a], sb[self._wr_a], wb, sb[self._wr_a]])
        end_body = np.concatenate([sb[self._st_b], wb, sb[self._wr_b], sb[self._wr_b]])
        weight = np.concatenate([np.ones(len(self._st_m)), wrapped, wrapped, ~wrapped]).astype(float)
        muscle = np.concatenate([self._st_m, self._wr_m, self._wr_m, self._wr_m])

        seg = ends - starts
        u, seglen = _normalize(seg)
        lengths = np.bincount(muscle, weights=weight * seglen, minlength=self.n_muscles)
        lengths += np.bincount(self._wr_m, weights=np.where(wrapped, wlen, 0.0), minlength=self.n_muscles)

        # d(length)/dq: u . (J_end - J_start); J of point p on body b, column k:
        #   revolute: moves[b, k] * axis_k x (p - o_k);  prismatic: moves[b, k] * axis_k
        # u . (a x (p - o)) = (p - o) . (u x a)
        uxa = np.cross(u[:, None, :], axes[None, :, :])  # (ns, nc, 3)
        def proj(p, b):
            rot = np.einsum("snk,snk->sn", p[:, None, :] - origins[None, :, :], uxa)
            lin = u @ axes.T
            return self._moves[b] * np.where(self._revolute[None, :], rot, lin)
        dl = (proj(ends, end_body) - proj(starts, start_body)) * weight[:, None]
        grad = np.zeros((self.n_muscles, self.n_coords))
        np.add.at(grad, muscle, dl)
        state = PathState(lengths=lengths, moment_arms=-grad)
        if v is not None:
            state.velocities = grad @ np.asarray(v, dtype=float)
        return state
