"""The mathematics of stability analysis on plain arrays (no model): energy Hessians, the
characteristic roots of a linear system with one delay, critical values by bisection.

* Static (Bergmark 1989): the Hessian of the potential energy about a posture,
  ``H = H_gravity + K_bushings + sum_i F_i d2L_i/dq2 + R^T diag(k) R`` with tendon forces F,
  musculotendon lengths L, moment arms R = -dL/dq and path stiffnesses k = dF/dL. The posture
  is statically stable when H is positive definite; its smallest eigenvalue (Nm/rad) is the
  stability index used here and its eigenvector the least-stable mode.
* Dynamic: ``x' = A0 x(t) + A1 x(t - tau)``. The rightmost roots of
  ``det(s I - A0 - A1 exp(-s tau)) = 0`` come from a spectral (Chebyshev collocation)
  discretisation of the delay equation's infinitesimal generator (Breda, Maset & Vermiglio 2005),
  in which only the delayed signals (the columns where A1 is non-zero) carry a history, and are
  then polished by Newton's method on the exact characteristic equation. Without a delay they are
  the eigenvalues of A0 + A1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

CHEBYSHEV_NODES = 16  # collocation nodes on [-tau, 0]; the rightmost roots converge spectrally
NEWTON_STEPS = 12
NEWTON_ROOTS = 8  # the rightmost roots polished on the exact equation
NEWTON_REACH = 30.0  # roots with Re(s) * tau below -NEWTON_REACH are left as discretised


@dataclass
class StaticStability:
    """The energy Hessian about a posture (Nm/rad; N/m for translations) and what it says."""

    coordinates: list[str]
    hessian: np.ndarray
    terms: dict  # name -> (n, n) contribution: gravity, bushings, muscle_geometry, muscle_stiffness, short_range
    eigenvalues: np.ndarray  # ascending
    modes: np.ndarray  # (n, n), columns; each scaled to a largest entry of +1

    @property
    def stable(self) -> bool:
        return bool(self.eigenvalues[0] > 0)

    @property
    def stability_index(self) -> float:
        """The smallest eigenvalue of the Hessian (Nm/rad): > 0 statically stable."""
        return float(self.eigenvalues[0])

    @property
    def least_stable_mode(self) -> np.ndarray:
        return self.modes[:, 0]

    def summary(self) -> dict:
        return {"stable": self.stable, "stability_index_nm_per_rad": self.stability_index,
                "eigenvalues_nm_per_rad": self.eigenvalues.tolist(),
                "least_stable_mode": dict(zip(self.coordinates, self.least_stable_mode.tolist())),
                "terms_along_least_stable_mode_nm_per_rad": {
                    name: float(self.least_stable_mode @ term @ self.least_stable_mode / (self.least_stable_mode @ self.least_stable_mode))
                    for name, term in self.terms.items()}}


def static_stability(coordinates, gravity_hessian, bushing_stiffness, tendon_force, length_hessian, moment_arms,
                     path_stiffness, short_range_stiffness=None) -> StaticStability:
    """Energy Hessian from its parts: `gravity_hessian` (n, n) = -d(gravity generalized force)/dq,
    `bushing_stiffness` (n,) or (n, n), `tendon_force` (m,) N, `length_hessian` (m, n, n) = d2L/dq2,
    `moment_arms` (m, n) = -dL/dq, `path_stiffness` (m,) = dF/dL in N/m (force-length slope at fixed
    activation) and optionally `short_range_stiffness` (m,) N/m."""
    R = np.atleast_2d(np.asarray(moment_arms, float))
    n = R.shape[1]
    bushing = np.asarray(bushing_stiffness, float)
    terms = {
        "gravity": np.asarray(gravity_hessian, float).reshape(n, n),
        "bushings": np.diag(np.broadcast_to(bushing, (n,))) if bushing.ndim < 2 else bushing,
        "muscle_geometry": np.einsum("i,ijk->jk", np.asarray(tendon_force, float), np.asarray(length_hessian, float)),
        "muscle_stiffness": R.T @ (np.asarray(path_stiffness, float)[:, None] * R),
    }
    if short_range_stiffness is not None:
        terms["short_range"] = R.T @ (np.asarray(short_range_stiffness, float)[:, None] * R)
    hessian = sum(terms.values())
    hessian = 0.5 * (hessian + hessian.T)
    values, vectors = np.linalg.eigh(hessian)
    return StaticStability(list(coordinates), hessian, terms, values, np.column_stack([unit_shape(v) for v in vectors.T]))


def unit_shape(vector) -> np.ndarray:
    """A (possibly complex) mode as a real shape: phase-aligned to its largest entry, scaled to +1 there."""
    v = np.asarray(vector)
    k = int(np.argmax(np.abs(v)))
    return np.real(v / v[k]) if np.abs(v[k]) > 0 else np.real(v)


# ------------------------------------------------------------------------------- delay equations

def characteristic_roots(a0, a1=None, delay: float = 0.0, nodes: int = CHEBYSHEV_NODES) -> tuple[np.ndarray, np.ndarray]:
    """Roots s of det(s I - A0 - A1 exp(-s delay)) and their right null vectors, rightmost first.

    Without a delay (or A1 = 0) these are the eigenvalues of A0 + A1. With one, the rightmost
    NEWTON_ROOTS roots of the spectral discretisation are refined by Newton's method on the exact
    equation; roots farther left (spurious discretisation roots among them) are returned as discretised.
    """
    a0 = np.asarray(a0, float)
    a1 = np.zeros_like(a0) if a1 is None else np.asarray(a1, float)
    delayed = np.flatnonzero(np.any(a1 != 0.0, axis=0))
    if delay <= 0.0 or not delayed.size:
        values, vectors = np.linalg.eig(a0 + a1)
        order = np.argsort(-values.real)
        return values[order], vectors[:, order]
    n, p = a0.shape[0], delayed.size
    theta, D = _chebyshev(nodes, delay)
    big = np.zeros((n + p * nodes, n + p * nodes))
    big[:n, :n] = a0
    big[:n, n + p * (nodes - 1):] = a1[:, delayed]  # the history at theta = -delay
    C = np.zeros((p, n))
    C[np.arange(p), delayed] = 1.0
    for j in range(1, nodes + 1):
        rows = slice(n + p * (j - 1), n + p * j)
        big[rows, :n] = D[j, 0] * C
        for k in range(1, nodes + 1):
            big[rows, n + p * (k - 1): n + p * k] = D[j, k] * np.eye(p)
    values, vectors = np.linalg.eig(big)
    order = np.argsort(-values.real)
    values, vectors = values[order], vectors[:n, order].astype(complex)
    near = np.flatnonzero(values.real * delay > -NEWTON_REACH)[:NEWTON_ROOTS]  # far left: exp(-s tau) overflows
    for k in near:
        values[k], vectors[:, k] = refine_root(a0, a1, delay, values[k], vectors[:, k])
    order = np.argsort(-values.real)
    return values[order], vectors[:, order]


def _chebyshev(nodes: int, delay: float):
    """Chebyshev extremal points theta_0 = 0 > ... > theta_N = -delay and the differentiation matrix."""
    j = np.arange(nodes + 1)
    x = np.cos(np.pi * j / nodes)
    c = np.where((j == 0) | (j == nodes), 2.0, 1.0) * (-1.0) ** j
    X = x[:, None] - x[None, :]
    D = np.outer(c, 1.0 / c) / (X + np.eye(nodes + 1))
    D -= np.diag(D.sum(axis=1))
    return delay / 2.0 * (x - 1.0), D * (2.0 / delay)


def refine_root(a0, a1, delay, s, v):
    """The root and null vector nearest (s, v): Newton on T(s) v = 0, T(s) = s I - A0 - A1 exp(-s delay),
    with the normalisation c^H v = 1 (in real arithmetic when s and v are real)."""
    n = a0.shape[0]
    real = np.isreal(s) and np.all(np.isreal(v))
    dtype = float if real else complex
    s, v = (float(np.real(s)), np.real(v).astype(float)) if real else (complex(s), np.asarray(v, complex))
    if not np.any(v):
        return s, v
    c = (v / (v @ v.conj())).conj()
    J = np.zeros((n + 1, n + 1), dtype)
    J[n, :n] = c
    rhs = np.empty(n + 1, dtype)
    for _ in range(NEWTON_STEPS):
        e = np.exp(-s * delay)
        J[:n, :n] = -a0 - a1 * e if delay > 0 else -(a0 + a1)
        J[np.arange(n), np.arange(n)] += s
        # [T  T' v; c^H 0] [dv; ds] = -[T v; c^H v - 1],  T' = I + delay A1 exp(-s delay)
        J[:n, n] = v + (delay * e) * (a1 @ v)
        rhs[:n], rhs[n] = -(J[:n, :n] @ v), 1.0 - c @ v
        try:
            step = np.linalg.solve(J, rhs)
        except np.linalg.LinAlgError:
            break
        v, s = v + step[:n], s + step[n]
        if abs(step[n]) <= 1e-12 * max(1.0, abs(s)):
            break
    return s, v


# ------------------------------------------------------------------------------- bisection

@dataclass
class CriticalValue:
    """The interval [value, upper] of a parameter in [low, high] over which `margin` < 0 (stable), others
    held: around the parameter's current value when that is stable, else the first one from `low`.
    value None: no stable value found; upper None: stable up to `high`."""

    name: str
    value: float | None
    low: float
    high: float
    unit: str
    evaluations: int
    note: str = ""
    upper: float | None = None

    def summary(self) -> dict:
        return {"value": self.value, "upper": self.upper, "unit": self.unit, "range": [self.low, self.high],
                "text": (self._interval() + (f" ({self.note})" if self.note else "")), "evaluations": self.evaluations}

    def _interval(self) -> str:
        if self.value is None:
            return f"{self.name}: none within [{self.low:.4g}, {self.high:.4g}] {self.unit}".rstrip()
        if self.upper is None:
            if self.value <= self.low:
                return f"{self.name} anywhere in [{self.low:.4g}, {self.high:.4g}] {self.unit}".rstrip()
            return f"{self.name} >= {self.value:.4g} {self.unit}".rstrip()
        if self.value <= self.low:
            return f"{self.name} in [{self.low:.4g}, {self.upper:.4g}] {self.unit} (from the range's lower end)".replace("  ", " ")
        return f"{self.name} in [{self.value:.4g}, {self.upper:.4g}] {self.unit}".rstrip()


def critical_value(name: str, margin, low: float, high: float, unit: str = "", rtol: float = 0.02,
                   log: bool = True, grid: int = 6, current: float | None = None) -> CriticalValue:
    """The stable interval of a parameter in [low, high]: `margin(value)` < 0 inside it. Anchored at
    `current` (the parameter's present value) when that is stable, else at the first stable point of a
    scan of `grid` points (log-spaced if `log` and low > 0) from `low`; each bound by bisection to `rtol`
    between the stable anchor side and the nearest unstable scan point. A stable window narrower than the
    scan's spacing can be missed, and only the one interval is reported."""
    count = 0
    geometric = log and low > 0

    def stable(x):
        nonlocal count
        count += 1
        return margin(x) < 0.0

    def bound(unstable, inside):
        while abs(inside - unstable) > rtol * max(abs(inside), abs(unstable)):
            mid = np.sqrt(unstable * inside) if geometric else 0.5 * (unstable + inside)
            unstable, inside = (unstable, mid) if stable(mid) else (mid, inside)
        return float(inside)

    points = list(np.geomspace(low, high, grid) if geometric else np.linspace(low, high, grid))
    if current is not None and low <= current <= high and stable(current):
        anchor = float(current)
    else:
        anchor = next((float(p) for p in points if stable(p)), None)
    if anchor is None:
        return CriticalValue(name, None, low, high, unit, count)
    lower, upper = float(low), None
    inside = anchor
    for p in sorted((p for p in points if p < anchor), reverse=True):
        if not stable(p):
            lower = bound(p, inside)
            break
        inside = p
    inside = anchor
    for p in sorted(p for p in points if p > anchor):
        if not stable(p):
            upper = bound(p, inside)
            break
        inside = p
    note = "" if current is None else f"now {current:.4g}"
    return CriticalValue(name, lower, low, high, unit, count, note, upper)
