"""OpenSim's wrapping algorithms, compiled with numba (our implementation of OpenSim 4.6's semantics).

Each function wraps the straight line between two points given in the wrap surface's own frame
and returns (status, wrapped length) with the tangent points written to `r1`, `r2`:

* sphere (`WrapSphere`): tangent points in the plane of the centre and both points, wrapping
  only when the line passes through the sphere;
* cylinder (`WrapCylinder`, axis z, finite length): tangent points slid along the surface lines
  until they lie in the plane through both points and the apex of the cylinder, a helical arc
  between them; a path with several wraps also adjusts each tangent point until the line meets
  the helix within 0.1 deg;
* ellipsoid (`WrapEllipsoid`): the wrapping plane from the line's closest surface points
  ("hybrid" blends the axis-plane and the fan estimate), tangent points by a damped
  least-squares iteration, length of a polyline of at most 499 pieces along the cut.

A quadrant ("x", "-y", ...) keeps the wrap on one side of the surface: `axis` (0, 1, 2) and
`sign` (+1, -1; 0 for "all"). Status: NO_WRAP, INSIDE (a point inside the surface), WRAPPED (a
candidate, the path keeps the shortest) or MANDATORY (the line passes through the surface).
The OpenSim semantics are kept where they are surprising, e.g. a far-side sphere wrap has a
negative arc length and a constrained cylinder accepts a segment only within 1 m of its start.
"""

from __future__ import annotations

import math

import numba
import numpy as np

NO_WRAP, INSIDE, WRAPPED, MANDATORY = 0, 1, 2, 3
METHODS = {"hybrid": 0, "midpoint": 1, "axial": 2}
_EPS = float(np.finfo(float).eps)
_ROUNDOFF = 2e-13
_LINE_EPS = 1e-5
_TANGENCY = 0.1 * math.pi / 180.0
_MU_MIN, _MU_MAX, _FAN, _SV_BLEND = 0.7073, 0.9, 300, 0.3

_jit = numba.njit(cache=True, fastmath=False, error_model="numpy")


@_jit
def _dsign(x):
    return 1 if x >= 0.0 else -1


@_jit
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@_jit
def _cross(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


@_jit
def _unit(v):
    """v / |v| (zero for a zero vector), and |v|."""
    mag = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    if mag >= _EPS:
        return v * (1.0 / mag), mag
    return np.zeros(3), mag


@_jit
def _closest_on_line(pt, line_pt, line):
    """Closest point to `pt` on the line through `line_pt` along `line`, and its parameter."""
    v1, mag = _unit(pt - line_pt)
    v2, mag2 = _unit(line)
    t = _dot(v1, v2) * mag
    return line_pt + t * v2, (t / mag2 if mag2 > 0.0 else t)


@_jit
def _intersect_lines(p1, p2, p3, p4):
    """Closest points of lines p1-p2 and p3-p4: (point on 1, s, point on 2, t, found)."""
    vec1, mag1 = _unit(p2 - p1)
    vec2, mag2 = _unit(p4 - p3)
    cr = _cross(vec1, vec2)
    denom = _dot(cr, cr)
    if abs(denom) <= _ROUNDOFF:
        return np.full(3, np.nan), np.nan, np.full(3, np.nan), np.nan, False
    d = p3 - p1
    t = _dot(d, _cross(vec1, cr)) / denom  # det of the rows (d, vec1, cr)
    s = _dot(d, _cross(vec2, cr)) / denom
    return p1 + s * vec1, s / mag1, p3 + t * vec2, t / mag2, True


@_jit
def _sphere_candidates(p, n, radius):
    """Tangent candidates from p in the plane normal to n: p + |p| cos(a) (cos(a) y -/+ sin(a) z)."""
    y, _ = _unit(-p)
    z = _cross(n, y)
    norm = math.sqrt(_dot(p, p))
    ang = math.asin(radius / norm)
    scale = norm * math.cos(ang)
    ca, sa = math.cos(ang), math.sin(ang)
    return p + scale * (ca * y - sa * z), p + scale * (ca * y + sa * z)


@_jit
def _pick_pair(r1a, r1b, r2a, r2b, u1a, u1b, u2a, u2b):
    """The pair of tangent candidates whose unit radial vectors are closest (OpenSim's order)."""
    j1, j2, j3, j4 = _dot(u1a, u2a), _dot(u1a, u2b), _dot(u1b, u2a), _dot(u1b, u2b)
    if j1 > j2 and j1 > j3 and j1 > j4:
        return r1a, r2a, r1b, r2b
    if j2 > j3 and j2 > j4:
        return r1a, r2b, r1b, r2a
    if j3 > j4:
        return r1b, r2a, r1a, r2b
    return r1b, r2b, r1a, r2a


@_jit
def wrap_sphere(p1, p2, radius, axis, sign, r1, r2):
    """OpenSim sphere wrapping (centre at the origin); returns (status, arc length)."""
    if math.sqrt(_dot(p1, p1)) < radius or math.sqrt(_dot(p2, p2)) < radius:
        return INSIDE, 0.0
    ri = p1 - p2
    mp = -p2
    a = _dot(ri, ri)
    b = -2.0 * _dot(mp, ri)
    c = _dot(mp, mp) - radius * radius
    disc = b * b - 4.0 * a * c
    if disc < 0.0:
        return NO_WRAP, 0.0
    l1 = (-b + math.sqrt(disc)) / (2.0 * a)
    l2 = (-b - math.sqrt(disc)) / (2.0 * a)
    if not (0.0 < l1 < 1.0) or not (0.0 < l2 < 1.0) or l1 < l2:
        return NO_WRAP, 0.0
    p1p2, _ = _unit(p1 - p2)
    np2, _ = _unit(p2)
    hp2 = _cross(p1p2, np2)
    n, hn = _unit(hp2)
    if hn < 1e-5:  # the line passes through the centre: OpenSim reuses an earlier wrap; we do not wrap
        return NO_WRAP, 0.0
    r1a, r1b = _sphere_candidates(p1, n, radius)
    r2a, r2b = _sphere_candidates(p2, n, radius)
    u1a, _ = _unit(r1a)
    u1b, _ = _unit(r1b)
    u2a, _ = _unit(r2a)
    u2b, _ = _unit(r2b)
    t1, t2, o1, o2 = _pick_pair(r1a, r1b, r2a, r2b, u1a, u1b, u2a, u2b)
    status = WRAPPED
    far = False
    if sign != 0:
        s1, s2 = _dsign(p1[axis]), _dsign(p2[axis])
        if s1 == sign or s2 == sign:
            mm, tt = _closest_on_line(np.zeros(3), p1, p1p2)
            tt = -tt
            if _dot(mm, mm) < radius * radius and 0.0 < tt < 1.0:
                status = MANDATORY
            elif not (s1 != s2 and _dsign(mm[axis]) != sign):
                return NO_WRAP, 0.0
        if s1 != sign or s2 != sign:
            wrap_axis = np.zeros(3)
            wrap_axis[axis] = sign
            sm, _ = _unit(-p1 - p2)
            if _dot(u1a, sm) > _dot(u1b, sm):
                t1, o1 = r1a, r1b
            else:
                t1, o1 = r1b, r1a
            if _dot(u2a, sm) > _dot(u2b, sm):
                t2, o2 = r2a, r2b
            else:
                t2, o2 = r2b, r2a
            sm, _ = _unit((t1 - p1) + (t2 - p2))
            if _dot(sm, wrap_axis) < 0.0:
                t1, t2 = o1, o2
            if _dot(t1 + t2, (t1 - p1) + (t2 - p2)) < 0.0:
                far = True
    r1[:] = t1
    r2[:] = t2
    n1, _ = _unit(t1)
    n2, _ = _unit(t2)
    angle = math.acos(_dot(n1, n2))
    if far:
        angle = -(2.0 * math.pi - angle)
    return status, radius * angle


# ------------------------------------------------------------------------------ cylinder

_P0 = np.array([0.0, 0.0, -1.0])
_DN = np.array([0.0, 0.0, 1.0])


@_jit
def _axis_rotation(angle):
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@_jit
def _adjust_tangent(pt, r, w):
    """Slide tangent point r along the cylinder until pt-r and r-w meet the axis at equal angles."""
    pr, _ = _unit(r - pt)
    rw, _ = _unit(w - r)
    alpha = math.acos(_dot(pr, _DN))
    omega = math.acos(_dot(rw, _DN))
    if abs(alpha - omega) <= _TANGENCY:
        return False
    p1a, _ = _closest_on_line(pt, r, _DN)
    w1a, _ = _closest_on_line(w, r, _DN)
    _, _, hit, _, _ = _intersect_lines(pt, w, p1a, w1a)
    r += 1.5 * (hit - r)
    return True


@_jit
def _helix(p1, p2, r1, r2, radius, long_wrap, single):
    """Length of the helix from r1 to r2 (tangent points adjusted in place for multi-wrap paths)."""
    sense = -1.0 if long_wrap else 1.0
    for adjustments in range(101):
        a1, _ = _closest_on_line(r1, _P0, _DN)
        a2, _ = _closest_on_line(r2, _P0, _DN)
        axial = _dot(a2 - a1, _DN)
        uu, vv = r1 - a1, r2 - a2
        theta = math.atan2(_dot(_cross(uu, vv), _DN), _dot(uu, vv))
        if long_wrap:
            theta = 2.0 * math.pi - theta
        x = radius * theta
        length = math.sqrt(x * x + axial * axial)
        n_seg = max(1, int(length / 0.002))
        if single or n_seg < 2 or adjustments >= 100:
            return length
        t = 1.0 / n_seg
        w1 = _axis_rotation(sense * t * theta) @ r1 + _DN * (t * axial)
        moved1 = _adjust_tangent(p1, r1, w1)
        w2 = _axis_rotation(sense * (1.0 - t) * theta) @ r1 + _DN * ((1.0 - t) * axial)
        moved2 = _adjust_tangent(p2, r2, w2)
        if not (moved1 or moved2):
            return length
    return length


@_jit
def _cylinder_candidates(p, radius):
    near, _ = _closest_on_line(p, _P0, _DN)
    vv, dist0 = _unit(p - near)
    d = radius * (radius / dist0)
    pp = near + d * vv
    d = math.sqrt(radius * radius - d * d)
    uu = _cross(_DN, vv)
    return pp + d * uu, pp - d * uu, near, dist0


@_jit
def wrap_cylinder(p1, p2, radius, length, axis, sign, single, r1, r2):
    """OpenSim cylinder wrapping (axis z through the origin); returns (status, helix length)."""
    rr = radius * radius
    if p1[0] ** 2 + p1[1] ** 2 < rr or p2[0] ** 2 + p2[1] ** 2 < rr:
        return INSIDE, 0.0
    near12, t12, near00, _, _ = _intersect_lines(p1, p2, np.array([0.0, 0.0, -0.5 * length]),
                                                 np.array([0.0, 0.0, 0.5 * length]))
    crosses = _dot(near12 - near00, near12 - near00) < rr and 0.0 < t12 < 1.0
    constrained = sign != 0
    status = WRAPPED
    if not constrained:
        if not crosses:
            return NO_WRAP, 0.0
        status = MANDATORY
    r1a, r1b, p11, d1 = _cylinder_candidates(p1, radius)
    r2a, r2b, p22, d2 = _cylinder_candidates(p2, radius)
    far = long_wrap = False
    if constrained:
        s1, s2 = _dsign(p1[axis]), _dsign(p2[axis])
        if s1 == sign or s2 == sign:
            if crosses:
                status = MANDATORY
            elif not (s1 != s2 and _dsign(near12[axis]) != sign):
                return NO_WRAP, 0.0
        m1a, m1b, m2a, m2b = r1a - p11, r1b - p11, r2a - p22, r2b - p22
        alpha = math.acos(_dot(m1a, m2b) / (math.sqrt(_dot(m1a, m1a)) * math.sqrt(_dot(m2b, m2b))))
        beta = math.acos(_dot(m1b, m2a) / (math.sqrt(_dot(m1b, m1b)) * math.sqrt(_dot(m2a, m2a))))
        on1a, on1b = _dsign(r1a[axis]) == sign, _dsign(r1b[axis]) == sign
        on2a, on2b = _dsign(r2a[axis]) == sign, _dsign(r2b[axis]) == sign
        use_b_a = True  # (r1b, r2a) rather than (r1a, r2b)
        if on1a and on1b:
            use_b_a = on2a
        elif on1a:
            use_b_a = False
        elif on1b:
            use_b_a = True
        elif on2a:
            use_b_a = True
        elif on2b:
            use_b_a = False
        else:
            use_b_a = not (alpha > beta)
        if use_b_a:
            t1, t2 = r1b.copy(), r2a.copy()
            far = not (alpha > beta)
        else:
            t1, t2 = r1a.copy(), r2b.copy()
            far = alpha > beta
        if not (on1a or on1b or on2a or on2b):
            far = True
        if _dot((t1 - p11) + (t2 - p22), (t1 - p1) + (t2 - p2)) < 0.0:
            long_wrap = True
    else:
        u1a, _ = _unit(r1a - p11)
        u1b, _ = _unit(r1b - p11)
        u2a, _ = _unit(r2a - p22)
        u2b, _ = _unit(r2b - p22)
        t1, t2, _, _ = _pick_pair(r1a, r1b, r2a, r2b, u1a, u1b, u2a, u2b)
        t1, t2 = t1.copy(), t2.copy()
    # slide the tangent points along the surface into the plane of both points and the apex
    mpt = p1 + (d1 / (d1 + d2)) * (p2 - p1)
    axispt, _ = _closest_on_line(mpt, _P0, _DN)
    l1, _ = _unit(p1 - axispt)
    l2, _ = _unit(p2 - axispt)
    pn, _ = _unit(_cross(l1, l2))
    v1, _ = _unit(_cross(_DN, pn))
    v2, _ = _unit(_cross(pn, _DN))
    apex1, apex2 = axispt + radius * v1, axispt + radius * v2
    first_closer = _dot(mpt - apex1, mpt - apex1) < _dot(mpt - apex2, mpt - apex2)
    apex = apex2 if first_closer == far else apex1
    uu, _ = _unit(p1 - apex)
    vv, _ = _unit(p2 - apex)
    pn, _ = _unit(_cross(uu, vv))
    d = -_dot(p1, pn)
    for k in range(2):
        t = t1 if k == 0 else t2
        own, other = (p11, p22) if k == 0 else (p22, p11)
        lo, hi = t - 10.0 * _DN, t + 10.0 * _DN
        vec = hi - lo
        dp = _dot(vec, pn)
        if abs(dp) < _LINE_EPS:
            continue
        s = (-d - _dot(pn, lo)) / dp
        if s < -_LINE_EPS or s > 1.0 + _LINE_EPS:
            continue
        hit = lo + s * vec
        proj, _ = _closest_on_line(hit, own, other)
        if _dot(proj - other, proj - other) < _dot(own - other, own - other):
            t[:] = hit
    half = 0.5 * length
    if (t1[2] < -half or t1[2] > half) and (t2[2] < -half or t2[2] > half):
        return NO_WRAP, 0.0
    wlen = _helix(p1, p2, t1, t2, radius, long_wrap, single)
    r1[:] = t1
    r2[:] = t2
    return status, wlen


# ------------------------------------------------------------------------------ ellipsoid

@_jit
def _closest_on_ellipse(a, b, u, v):
    """Closest point (x, y) on the ellipse (x/a)^2 + (y/b)^2 = 1 to (u, v) (Eberly's Newton)."""
    a2, b2 = a * a, b * b
    a2u2, b2v2 = a2 * u * u, b2 * v * v
    near_x, near_y = abs(u) <= _ROUNDOFF, abs(v) <= _ROUNDOFF
    if near_x and near_y:
        if a < b:
            return (-a if u < 0.0 else a), v
        return u, (-b if v < 0.0 else b)
    if near_x:
        if a >= b or abs(v) >= b - a2 / b:
            return u, (b if v >= 0 else -b)
        y = b2 * v / (b2 - a2)
        return a * math.sqrt(abs(1 - (y / b) ** 2)), y
    if near_y:
        if b >= a or abs(u) >= a - b2 / a:
            return (a if u >= 0 else -a), v
        x = a2 * u / (a2 - b2)
        return x, b * math.sqrt(abs(1 - (x / a) ** 2))
    t = 0.0 if (u / a) ** 2 + (v / b) ** 2 < 1.0 else max(a, b) * math.sqrt(u * u + v * v)
    P = Q = 1.0
    for _ in range(64):
        P, Q = t + a2, t + b2
        f = P * P * Q * Q - a2u2 * Q * Q - b2v2 * P * P
        if abs(f) < 1e-9:
            break
        fp = 2.0 * (P * Q * (P + Q) - a2u2 * Q - b2v2 * P)
        t -= f / fp
    return a2 * u / P, b2 * v / Q


@_jit
def _closest_xyz(a0, a1, a2, u, v, w, axis, d0, d1, d2):
    """Closest surface point (x, y, z) to (u, v, w) on the ellipsoid with semi-axes a (Eberly's
    Newton); `axis` >= 0 forces the 2-D case in that coordinate plane, -1 picks it for points
    on a coordinate plane (the one with the narrowest section, sizes d)."""
    if axis < 0:
        best = np.inf
        sums = (d1 + d2, d0 + d2, d0 + d1)
        coords = (u, v, w)
        for i in range(3):
            if abs(coords[i]) <= _ROUNDOFF and best > sums[i]:
                axis, best = i, sums[i]
    if axis == 0:
        y, z = _closest_on_ellipse(a1, a2, v, w)
        return u, y, z
    if axis == 1:
        z, x = _closest_on_ellipse(a2, a0, w, u)
        return x, v, z
    if axis == 2:
        x, y = _closest_on_ellipse(a0, a1, u, v)
        return x, y, w
    a2_, b2, c2 = a0 * a0, a1 * a1, a2 * a2
    a2u2, b2v2, c2w2 = a2_ * u * u, b2 * v * v, c2 * w * w
    t = 0.0 if (u / a0) ** 2 + (v / a1) ** 2 + (w / a2) ** 2 < 1.0 else max(a0, a1, a2) * math.sqrt(u * u + v * v + w * w)
    P = Q = R = 1.0
    for _ in range(64):
        P, Q, R = t + a2_, t + b2, t + c2
        f = P * P * Q * Q * R * R - a2u2 * Q * Q * R * R - b2v2 * P * P * R * R - c2w2 * P * P * Q * Q
        if abs(f) < 1e-9:
            break
        fp = 2.0 * (P * Q * R * (Q * R + P * R + P * Q) - a2u2 * Q * R * (Q + R) - b2v2 * P * R * (P + R) - c2w2 * P * Q * (P + Q))
        t -= f / fp
    return a2_ * u / P, b2 * v / Q, c2 * w / R


@_jit
def _closest_on_ellipsoid(a, pt, axis, dims):
    x, y, z = _closest_xyz(a[0], a[1], a[2], pt[0], pt[1], pt[2], axis, dims[0], dims[1], dims[2])
    return np.array([x, y, z])


@_jit
def _fan_direction(a, s1, s12, dims):
    """Unit sum of the directions from the points of the segment to their closest surface points."""
    sx = sy = sz = 0.0
    for i in range(1, _FAN - 1):
        f = i / _FAN
        u, v, w = s1[0] + f * s12[0], s1[1] + f * s12[1], s1[2] + f * s12[2]
        x, y, z = _closest_xyz(a[0], a[1], a[2], u, v, w, -1, dims[0], dims[1], dims[2])
        dx, dy, dz = x - u, y - v, z - w
        mag = math.sqrt(dx * dx + dy * dy + dz * dz)
        if mag >= _EPS:
            inv = 1.0 / mag
            sx, sy, sz = sx + dx * inv, sy + dy * inv, sz + dz * inv
    out, _ = _unit(np.array([sx, sy, sz]))
    return out


@_jit
def _ssq(e):
    return e[0] * e[0] + e[1] * e[1] + e[2] * e[2] + e[3] * e[3]


@_jit
def _tangent_residuals(r, d, p, a, vs, vs4):
    nr = 2.0 * r / (a * a)
    e = np.empty(4)
    e[0] = _dot(vs, r) + vs4
    e[1] = (r[0] / a[0]) ** 2 + (r[1] / a[1]) ** 2 + (r[2] / a[2]) ** 2 - 1.0
    e[2] = _dot(nr, r) + d
    e[3] = _dot(nr, p) + d
    return e


@_jit
def _tangent_point(pe, r, p, a, vs, vs4):
    """Move r (on the ellipsoid) to where the line from p touches it within the plane (vs, vs4)."""
    if abs(pe) < 1e-4:
        r[:] = p
        return
    d = -_dot(2.0 * r / (a * a), r)
    e = _tangent_residuals(r, d, p, a, vs, vs4)
    ssq = ssq_old = _ssq(e)
    alpha = 0.01
    J = np.zeros((4, 4))
    J[3, 2] = J[3, 3] = 1.0
    vt = np.zeros(4)
    for _ in range(50):
        if ssq <= 1e-8:
            break
        for i in range(3):
            J[i, 0] = vs[i]
            J[i, 1] = 2.0 * r[i] / a[i] ** 2
            J[i, 2] = 2.0 * (2.0 * r[i]) / a[i] ** 2
            J[i, 3] = 2.0 * p[i] / a[i] ** 2
        pr, _ = _unit(p - r)
        pm, _ = _unit(p)
        pcos = _dot(pr, pm)
        damp = 1.0 - pcos ** 100 if pcos > 0.1 else 1.0
        v = -(J @ e)
        H = J @ J.T
        diag = np.diag(H).copy()
        k = 0
        while ssq >= ssq_old and k < 1000:
            for i in range(4):
                H[i, i] = diag[i] * (1.0 + alpha)
            vt = damp * (np.linalg.inv(H) @ v) / 16.0
            r += vt[:3]
            d += vt[3]
            e = _tangent_residuals(r, d, p, a, vs, vs4)
            ssq_old, ssq = ssq, _ssq(e)
            alpha *= 4.0
            k += 1
        alpha /= 8.0
        fakt = 0.5
        k = 0
        while ssq <= ssq_old and k < 1000:
            fakt *= 2.0
            r += vt[:3] * fakt
            d += vt[3] * fakt
            e = _tangent_residuals(r, d, p, a, vs, vs4)
            ssq_old, ssq = ssq, _ssq(e)
            k += 1
        r -= vt[:3] * fakt
        d -= vt[3] * fakt
        e = _tangent_residuals(r, d, p, a, vs, vs4)
        ssq = ssq_old = _ssq(e)


@_jit
def _surface_polyline(r1, r2, a, vs, vs4, far, factor, w1, w2):
    """Length of the cut of the ellipsoid by the wrapping plane from r1 to r2 (normalised units).

    w1, w2 receive the second and the second-to-last polyline points; returns (length, n_points).
    """
    chord = math.sqrt(_dot(r1 - r2, r1 - r2)) / factor
    if chord < 0.001:
        return chord * factor, 2
    n_seg = min(499, int(chord / 0.001))
    imax = 0
    for i in range(1, 3):
        if abs(vs[i]) > abs(vs[imax]):
            imax = i
    u = np.zeros(3)
    u[imax] = 1.0
    a0 = ((-vs4) / _dot(vs, u)) * u
    ar1, _ = _unit(r1 - a0)
    ar2, _ = _unit(r2 - a0)
    phi0 = math.acos(_dot(ar1, ar2))
    dphi = -(2.0 * math.pi - phi0) / n_seg if far else phi0 / n_seg
    z, _ = _unit(_cross(ar1, ar2))
    y = _cross(z, ar1)
    f2 = a0 / a
    cc = _dot(f2, f2) - 1.0
    prev = r1.copy()
    total = 0.0
    for i in range(n_seg - 1):
        phi = (i + 1) * dphi
        ray = math.cos(phi) * ar1 + math.sin(phi) * y
        f1 = ray / a
        aa, bb = _dot(f1, f1), 2.0 * _dot(f1, f2)
        pt = a0 + ((-bb + math.sqrt(bb * bb - 4.0 * aa * cc)) / (2.0 * aa)) * ray
        if i == 0:
            w1[:] = pt
        if i == n_seg - 2:
            w2[:] = pt
        total += math.sqrt(_dot(pt - prev, pt - prev))
        prev = pt
    total += math.sqrt(_dot(r2 - prev, r2 - prev))
    return total, n_seg + 1


@_jit
def wrap_ellipsoid(p1_in, p2_in, radii, axis, sign, method, r1, r2):
    """OpenSim ellipsoid wrapping (centre at the origin); returns (status, wrapped length)."""
    factor = 3.0 / (radii[0] + radii[1] + radii[2])
    p1, p2, a = p1_in * factor, p2_in * factor, radii * factor
    p1e = (p1[0] / a[0]) ** 2 + (p1[1] / a[1]) ** 2 + (p1[2] / a[2]) ** 2 - 1.0
    p2e = (p2[0] / a[0]) ** 2 + (p2[1] / a[1]) ** 2 + (p2[2] / a[2]) ** 2 - 1.0
    if p1e < -0.0001 or p2e < -0.0001:
        return INSIDE, 0.0
    p1p2 = p1 - p2
    u1, _ = _unit(p1)
    u2, _ = _unit(p2)
    if abs(_dot(u1, u2) - 1.0) < 0.0001:
        return NO_WRAP, 0.0
    f1, f2 = p1p2 / a, p2 / a
    aa, bb, cc = _dot(f1, f1), 2.0 * _dot(f1, f2), _dot(f2, f2) - 1.0
    disc = bb * bb - 4.0 * aa * cc
    if disc < 0.0:
        return NO_WRAP, 0.0
    l1 = (-bb + math.sqrt(disc)) / (2.0 * aa)
    l2 = (-bb - math.sqrt(disc)) / (2.0 * aa)
    if not (0.0 < l1 < 1.0) or not (0.0 < l2 < 1.0):
        return NO_WRAP, 0.0
    s1 = p2 + l1 * p1p2
    s2 = p2 + l2 * p1p2
    s12 = s2 - s1
    mu, _ = _unit(p1p2)
    mu = np.abs(mu)
    t = np.empty(3)
    t_sv = np.empty((3, 3))
    t_c1 = np.empty((3, 3))
    for i in range(3):
        t[i] = -s1[i] / s12[i]
        t_sv[i] = s1 + t[i] * s12
        t_c1[i] = _closest_on_ellipsoid(a, t_sv[i], i, radii)
    best = 0
    for i in range(1, 3):
        if mu[i] > mu[best]:
            best = i
    fan_weight = -np.inf
    c1 = np.zeros(3)
    if method == 1:  # midpoint
        c1 = _closest_on_ellipsoid(a, s1 + 0.5 * s12, -1, radii)
    else:
        if method == 0 and mu[best] > _MU_MIN:
            s = 1.0
            if t[best] < 0.0 or t[best] > 1.0:
                s = 0.0
            elif t[best] < _SV_BLEND:
                s = t[best] / _SV_BLEND
            elif t[best] > 1.0 - _SV_BLEND:
                s = (1.0 - t[best]) / _SV_BLEND
            if s < 1.0:
                mu[best] = _MU_MIN + s * (mu[best] - _MU_MIN)
        if method == 2 or mu[best] > _MU_MIN:
            c1 = t_c1[best].copy()
        if method == 0 and mu[best] < _MU_MAX:
            guess = s1 + 0.5 * s12 + _fan_direction(a, s1, s12, radii)
            if mu[best] <= _MU_MIN:
                c1 = _closest_on_ellipsoid(a, guess, -1, radii)
                fan_weight = 1.0
            else:
                tt = (mu[best] - _MU_MIN) / (_MU_MAX - _MU_MIN)
                fan = _closest_on_ellipsoid(a, guess, -1, radii)
                c1 = _closest_on_ellipsoid(a, tt * c1 + (1.0 - tt) * fan, -1, radii)
                fan_weight = 1.0 - tt
    t1 = c1.copy()
    if sign != 0 and _dsign(c1[axis]) != sign:
        orig = c1[axis]
        c1[axis] = -c1[axis]
        t1 = c1.copy()
        if abs(fan_weight - (-np.inf)) <= _ROUNDOFF:  # never true (inf - inf): kept as OpenSim has it
            fan_weight = 1.0 - (mu[best] - _MU_MIN) / (_MU_MAX - _MU_MIN)
        fan_weight = min(fan_weight, 1.0)
        if fan_weight > 0.0:
            c1[axis] = c1[axis] + fan_weight * (0.5 * (orig + c1[axis]) - c1[axis])
            c1 = _closest_on_ellipsoid(a, c1, -1, radii)
    t2 = t1.copy()
    vs, _ = _unit(_cross(p1p2, p1 - c1))
    vs4 = -_dot(vs, c1)
    _tangent_point(p1e, t1, p1, a, vs, vs4)
    _tangent_point(p2e, t2, p2, a, vs, vs4)
    w1, w2 = np.zeros(3), np.zeros(3)
    far = False
    length, n_pts = _surface_polyline(t1, t2, a, vs, vs4, far, factor, w1, w2)
    if sign != 0 and n_pts > 2:
        d1, _ = _unit(p1 - t1)
        e1, _ = _unit(w1 - t1)
        d2, _ = _unit(p2 - t2)
        e2, _ = _unit(w2 - t2)
        if _dot(d1, e1) > 0.0 or _dot(d2, e2) > 0.0:
            length, n_pts = _surface_polyline(t1, t2, a, vs, vs4, True, factor, w1, w2)
    r1[:] = t1 / factor
    r2[:] = t2 / factor
    return MANDATORY, length / factor
