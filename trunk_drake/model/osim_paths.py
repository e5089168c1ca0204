"""Muscle paths with OpenSim's semantics: active points, path wraps tried on every segment in range.

For each muscle the path is its active path points (conditional points drop out outside their
coordinate range; moving points move along their functions). Each path wrap is tried on every
segment between the first and last active point of its range; a segment the line crosses the
surface on is taken at once, otherwise the wrap that lengthens the path least; with several
wraps the passes repeat (at most 8) until the length changes by less than 0.5 mm, in the order
OpenSim uses (`GeometryPath::applyWrapObjects`). Wrap algorithms: `trunk_drake.model.osim_wrap`.

The length is the sum of the straight segments and the wrapped arcs. Moment arms follow
OpenSim's definition (the generalized force of a unit tension): each straight segment between
two different bodies pulls its end points together, the tangent points being fixed to the wrap
surface's body, plus the motion of moving path points along their coordinates. The kernel
returns the length gradient over the motion axes (the plant's coordinates first, then the axes
of bodies that follow other coordinates) and over q for the moving points.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from trunk_drake.model.osim_wrap import INSIDE, MANDATORY, METHODS, NO_WRAP, WRAPPED, wrap_cylinder, wrap_ellipsoid, wrap_sphere
from trunk_drake.model.paths import add_pull, axis_moments, quat_matrix, site_positions
from trunk_drake.model.spec import ModelSpec

_jit = numba.njit(cache=True, fastmath=False, error_model="numpy")
_KINDS = {"sphere": 0, "cylinder": 1, "ellipsoid": 2}
_AXES = {"all": (0, 0), "x": (0, 1), "-x": (0, -1), "y": (1, 1), "-y": (1, -1), "z": (2, 1), "-z": (2, -1)}


@_jit
def _wrap_point_id(w, k):
    return -(1 + 2 * w + k)


@_jit
def _entry_into(e, P, pw_r, Rw, cw, pw_obj, out):
    """Write the current world position of a path entry (site or wrap tangent point) into out."""
    if e >= 0:
        out[0], out[1], out[2] = P[e, 0], P[e, 1], P[e, 2]
        return
    w, k = (-e - 1) // 2, (-e - 1) % 2
    o = pw_obj[w]
    for r in range(3):
        out[r] = Rw[o, r, 0] * pw_r[w, k, 0] + Rw[o, r, 1] * pw_r[w, k, 1] + Rw[o, r, 2] * pw_r[w, k, 2] + cw[o, r]


@_jit
def _entry_position(e, P, pw_r, Rw, cw, pw_obj):
    out = np.empty(3)
    _entry_into(e, P, pw_r, Rw, cw, pw_obj, out)
    return out


@_jit
def _ground_into(e, P, pw_r, Rw, cw, pw_obj, gpos, gset, out):
    """An entry's position in ground as OpenSim reads it: a wrap point keeps the position it had
    when first read at this pose (OpenSim caches Point::getLocationInGround per state), even
    after a later wrap pass moves it."""
    if e >= 0:
        out[0], out[1], out[2] = P[e, 0], P[e, 1], P[e, 2]
        return
    w, k = (-e - 1) // 2, (-e - 1) % 2
    if not gset[w, k]:
        _entry_into(e, P, pw_r, Rw, cw, pw_obj, gpos[w, k])
        gset[w, k] = True
    out[0], out[1], out[2] = gpos[w, k, 0], gpos[w, k, 1], gpos[w, k, 2]


@_jit
def _ground(e, P, pw_r, Rw, cw, pw_obj, gpos, gset):
    out = np.empty(3)
    _ground_into(e, P, pw_r, Rw, cw, pw_obj, gpos, gset, out)
    return out


@_jit
def _remove_wrap(ent, n, w):
    """Remove path wrap w's two tangent points from the entry list; returns the new count."""
    first = _wrap_point_id(w, 0)
    for j in range(n):
        if ent[j] == first:
            for k in range(j, n - 2):
                ent[k] = ent[k + 2]
            return n - 2
    return n


@_jit
def _path_length(ent, n, P, pw_r, pw_len, Rw, cw, pw_obj, gpos, gset):
    total = 0.0
    for j in range(n - 1):
        a, b = ent[j], ent[j + 1]
        if a < 0 and b < 0 and pw_obj[(-a - 1) // 2] == pw_obj[(-b - 1) // 2]:
            if (-b - 1) % 2 == 1:
                total += pw_len[(-b - 1) // 2]
            continue
        d = _ground(b, P, pw_r, Rw, cw, pw_obj, gpos, gset) - _ground(a, P, pw_r, Rw, cw, pw_obj, gpos, gset)
        total += math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
    return total


@_jit
def _wrap_segment(x1, x2, o, Rw, cw, wo_kind, wo_dims, wo_axis, wo_sign, method, single, r1, r2):
    l1 = Rw[o].T @ (x1 - cw[o])
    l2 = Rw[o].T @ (x2 - cw[o])
    kind = wo_kind[o]
    if kind == 0:
        return wrap_sphere(l1, l2, wo_dims[o, 0], wo_axis[o], wo_sign[o], r1, r2)
    if kind == 1:
        return wrap_cylinder(l1, l2, wo_dims[o, 0], wo_dims[o, 1], wo_axis[o], wo_sign[o], single, r1, r2)
    return wrap_ellipsoid(l1, l2, wo_dims[o], wo_axis[o], wo_sign[o], method, r1, r2)


@_jit
def _apply_wraps(ent, n, pts, site_active, P, pw_obj, pw_start, pw_end, pw_method, pw_r, pw_len, gpos, gset,
                 Rw, cw, wo_kind, wo_dims, wo_axis, wo_sign):
    """OpenSim's applyWrapObjects on one muscle; returns the new entry count."""
    n_w = pw_obj.shape[0]
    n_pts = pts.shape[0]
    order = np.arange(n_w)
    result = np.zeros(n_w, dtype=np.int64)
    r1, r2 = np.zeros(3), np.zeros(3)
    best_r1, best_r2 = np.zeros(3), np.zeros(3)
    last = np.inf
    for kk in range(1 if n_w < 2 else 8):
        for i in range(n_w):
            result[i] = NO_WRAP
            w = order[i]
            n = _remove_wrap(ent, n, w)
            lo = 0 if pw_start[w] < 1 else pw_start[w] - 1
            hi = n_pts - 1 if pw_end[w] < 1 else pw_end[w] - 1
            jf = lo
            while jf <= hi and not site_active[pts[jf]]:
                jf += 1
            jr = hi
            while jr >= lo and not site_active[pts[jr]]:
                jr -= 1
            if jf > hi or jr < lo:
                return n
            start = end = -1
            for j in range(n):
                if ent[j] == pts[jf]:
                    start = j
                if ent[j] == pts[jr]:
                    end = j
            best_end, best_len, best_change = -1, 0.0, np.inf
            for a in range(start, end):
                ea, eb = ent[a], ent[a + 1]
                if ea < 0 and eb < 0 and pw_obj[(-ea - 1) // 2] == pw_obj[(-eb - 1) // 2]:
                    continue
                x1 = _entry_position(ea, P, pw_r, Rw, cw, pw_obj)
                x2 = _entry_position(eb, P, pw_r, Rw, cw, pw_obj)
                o = pw_obj[w]
                status, wlen = _wrap_segment(x1, x2, o, Rw, cw, wo_kind, wo_dims, wo_axis, wo_sign,
                                             pw_method[w], n_w == 1, r1, r2)
                result[i] = status
                if status == MANDATORY:
                    best_end, best_len = a + 1, wlen
                    best_r1[:] = r1
                    best_r2[:] = r2
                    break
                if status == WRAPPED:
                    t1 = Rw[o] @ r1 + cw[o]
                    t2 = Rw[o] @ r2 + cw[o]
                    g1 = _ground(ea, P, pw_r, Rw, cw, pw_obj, gpos, gset)
                    g2 = _ground(eb, P, pw_r, Rw, cw, pw_obj, gpos, gset)
                    change = (math.sqrt(np.sum((g1 - t1) ** 2)) + wlen + math.sqrt(np.sum((g2 - t2) ** 2))
                              - math.sqrt(np.sum((g2 - g1) ** 2)))
                    if change < best_change:
                        best_end, best_len, best_change = a + 1, wlen, change
                        best_r1[:] = r1
                        best_r2[:] = r2
            if best_end >= 0:
                for k in range(n - 1, best_end - 1, -1):
                    ent[k + 2] = ent[k]
                ent[best_end] = _wrap_point_id(w, 0)
                ent[best_end + 1] = _wrap_point_id(w, 1)
                n += 2
                pw_r[w, 0, :] = best_r1
                pw_r[w, 1, :] = best_r2
                pw_len[w] = best_len
        length = _path_length(ent, n, P, pw_r, pw_len, Rw, cw, pw_obj, gpos, gset)
        if abs(length - last) < 0.0005:
            break
        last = length
        if kk == 0 and n_w > 1 and result[0] == NO_WRAP and result[1] == INSIDE:
            order[0], order[1] = 1, 0
            n = _remove_wrap(ent, n, 0)
    return n


@_jit
def _osim_kernel(R, p, axes, origins, revolute, moves, site_body, site_local, site_active, site_dw, site_moving,
                 mus_pt, mus_pw, pt_site, pw_wrap, pw_start, pw_end, pw_method,
                 wo_body, wo_pos, wo_rot, wo_kind, wo_dims, wo_axis, wo_sign, nq):
    P = site_positions(R, p, site_body, site_local)
    n_wo = wo_body.shape[0]
    Rw = np.empty((n_wo, 3, 3))
    cw = np.empty((n_wo, 3))
    for o in range(n_wo):
        b = wo_body[o]
        Rw[o] = R[b] @ wo_rot[o]
        cw[o] = R[b] @ wo_pos[o] + p[b]
    nc = axes.shape[0]
    axo = axis_moments(axes, origins)
    n_m = mus_pt.shape[0]
    lengths = np.zeros(n_m)
    grad = np.zeros((n_m, nc))
    grad_q = np.zeros((n_m, nq))
    X = np.empty((2, 3))  # ground positions as OpenSim reads them (pull direction, length)
    T = np.empty((2, 3))  # current positions (where the pull acts)
    max_w = max(1, np.max(mus_pw[:, 1]) if n_m else 1)
    ent_buf = np.empty(np.max(mus_pt[:, 1]) + 2 * max_w if n_m else 1, dtype=np.int64)
    pw_r, pw_len = np.zeros((max_w, 2, 3)), np.zeros(max_w)
    gpos, gset = np.zeros((max_w, 2, 3)), np.zeros((max_w, 2), dtype=np.bool_)
    for m in range(n_m):
        pts = pt_site[mus_pt[m, 0]:mus_pt[m, 0] + mus_pt[m, 1]]
        w0, n_w = mus_pw[m, 0], mus_pw[m, 1]
        pw_obj = pw_wrap[w0:w0 + n_w]
        ent = ent_buf
        n = 0
        for s in pts:
            if site_active[s]:
                ent[n] = s
                n += 1
        if n_w > 0:
            gset[:n_w] = False
            n = _apply_wraps(ent, n, pts, site_active, P, pw_obj, pw_start[w0:w0 + n_w], pw_end[w0:w0 + n_w],
                             pw_method[w0:w0 + n_w], pw_r, pw_len, gpos, gset, Rw, cw, wo_kind, wo_dims, wo_axis, wo_sign)
        for j in range(n - 1):
            a, b = ent[j], ent[j + 1]
            if a < 0 and b < 0 and pw_obj[(-a - 1) // 2] == pw_obj[(-b - 1) // 2]:
                if (-b - 1) % 2 == 1:
                    lengths[m] += pw_len[(-b - 1) // 2]
                continue
            ba = site_body[a] if a >= 0 else wo_body[pw_obj[(-a - 1) // 2]]
            bb = site_body[b] if b >= 0 else wo_body[pw_obj[(-b - 1) // 2]]
            _ground_into(a, P, pw_r, Rw, cw, pw_obj, gpos, gset, X[0])
            _ground_into(b, P, pw_r, Rw, cw, pw_obj, gpos, gset, X[1])
            d0, d1, d2 = X[1, 0] - X[0, 0], X[1, 1] - X[0, 1], X[1, 2] - X[0, 2]
            L = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            lengths[m] += L
            if ba == bb or L < 1e-15:
                continue
            # the tension pulls along the (first-read) ground positions, applied at the current points
            u0, u1, u2 = d0 / L, d1 / L, d2 / L
            _entry_into(a, P, pw_r, Rw, cw, pw_obj, T[0])
            _entry_into(b, P, pw_r, Rw, cw, pw_obj, T[1])
            add_pull(m, u0, u1, u2, T[0], ba, T[1], bb, revolute, moves, axes, axo, grad)
            if a >= 0 and site_moving[a]:
                for k in range(nq):
                    grad_q[m, k] -= u0 * site_dw[a, 0, k] + u1 * site_dw[a, 1, k] + u2 * site_dw[a, 2, k]
            if b >= 0 and site_moving[b]:
                for k in range(nq):
                    grad_q[m, k] += u0 * site_dw[b, 0, k] + u1 * site_dw[b, 1, k] + u2 * site_dw[b, 2, k]
    return lengths, grad, grad_q


class OsimPaths:
    """Path geometry of all muscles of an OpenSim ModelSpec on a given set of bodies.

    Like `MusclePaths`, with OpenSim wrapping. `axis_kinds[k]` is "hinge" or "slide" for every
    motion axis (plant coordinates, then follower axes) and `axis_moves[b, k]` is 1 where axis k
    moves body b.
    """

    def __init__(self, spec: ModelSpec, bodies: list[str], axis_kinds: list[str], axis_moves: np.ndarray, nq: int):
        index = {b: i for i, b in enumerate(bodies)}
        self.n_muscles, self.nq = len(spec.muscles), nq
        self._revolute = np.array([k == "hinge" for k in axis_kinds], dtype=np.bool_)
        self._moves = np.ascontiguousarray(axis_moves, dtype=float)
        self._site_body = np.array([index[s.body] for s in spec.sites], dtype=np.int64)
        self.site_local = np.array([s.pos for s in spec.sites], dtype=float).reshape(-1, 3)
        self.site_moving = np.array([s.motion is not None for s in spec.sites], dtype=np.bool_)
        pt_site, mus_pt, mus_pw, pws = [], [], [], []
        for mus in spec.muscles:
            mus_pt.append((len(pt_site), len(mus.path)))
            pt_site.extend(e.index for e in mus.path)
            mus_pw.append((len(pws), len(mus.path_wraps)))
            pws.extend(mus.path_wraps)
        self._pt_site = np.array(pt_site, dtype=np.int64)
        self._mus_pt = np.array(mus_pt, dtype=np.int64).reshape(-1, 2)
        self._mus_pw = np.array(mus_pw, dtype=np.int64).reshape(-1, 2)
        self._pw_wrap = np.array([w.wrap for w in pws], dtype=np.int64)
        self._pw_start = np.array([w.start for w in pws], dtype=np.int64)
        self._pw_end = np.array([w.end for w in pws], dtype=np.int64)
        self._pw_method = np.array([METHODS[w.method] for w in pws], dtype=np.int64)
        wraps = spec.wraps
        self._wo_body = np.array([index[w.body] for w in wraps], dtype=np.int64)
        self._wo_pos = np.array([w.pos for w in wraps], dtype=float).reshape(-1, 3)
        self._wo_rot = np.array([quat_matrix(w.quat) for w in wraps], dtype=float).reshape(-1, 3, 3)
        self._wo_kind = np.array([_KINDS[w.kind] for w in wraps], dtype=np.int64)
        self._wo_dims = np.array([w.radii if w.kind == "ellipsoid" else (w.radius, w.length, 0.0) for w in wraps],
                                 dtype=float).reshape(-1, 3)
        self._wo_axis = np.array([_AXES[w.quadrant][0] for w in wraps], dtype=np.int64)
        self._wo_sign = np.array([_AXES[w.quadrant][1] for w in wraps], dtype=np.int64)
        self._all_active = np.ones(len(spec.sites), dtype=np.bool_)
        self._no_dw = np.zeros((len(spec.sites), 3, nq))

    def bodies_used(self) -> set[int]:
        return {int(b) for b in self._site_body} | {int(b) for b in self._wo_body}

    def compute(self, R_body, p_body, axes, origins, site_local=None, site_active=None, site_dw=None):
        """(lengths, gradient over the motion axes, gradient over q from moving points)."""
        return _osim_kernel(
            np.ascontiguousarray(R_body), np.ascontiguousarray(p_body), np.ascontiguousarray(axes),
            np.ascontiguousarray(origins), self._revolute, self._moves, self._site_body,
            self.site_local if site_local is None else site_local,
            self._all_active if site_active is None else site_active,
            self._no_dw if site_dw is None else site_dw, self.site_moving,
            self._mus_pt, self._mus_pw, self._pt_site, self._pw_wrap, self._pw_start, self._pw_end, self._pw_method,
            self._wo_body, self._wo_pos, self._wo_rot, self._wo_kind, self._wo_dims, self._wo_axis, self._wo_sign,
            self.nq,
        )
