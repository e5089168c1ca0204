"""Is the seated trunk's posture stable, by what margin, in which mode, and what would make it so?

`stability(model, options, q)` answers for the diagram `build_trunk_diagram(model, options)`:

* **Operating point.** Stretch-reflex tone (``kp (l_n - l_d)+`` of every fiber beyond its set
  point) and small residuals of the co-activation make the requested posture (default:
  upright) not quite an equilibrium. Newton's method finds the closed-loop rest state nearest to
  it (v = 0, activation = excitation, SRS references at the fiber lengths); the result reports
  the unbalanced generalized force at the requested posture and the distance to that equilibrium.
* **Static** (Bergmark 1989; Cholewicki & McGill 1996): the energy Hessian there at the rest
  activations, with gravity (finite differences of the plant's gravity forces), the bushings and
  the muscles: ``F d2L/dq2`` (finite differences of the analytic moment arms) plus
  ``R^T diag(dF/dL) R`` with the Thelen force-length slope and, if switched on, short-range
  stiffness. Reflexes are not part of it.
* **Dynamic**: the characteristic roots of the closed loop linearised by central differences of
  the real diagram's time derivatives (`ClosedLoop.jacobian`, equal to `gap.linear.state_jacobian`
  at a fifteenth of its evaluations), with the stretch reflex
  (the only path from q, v to the activations' rates) as the delayed part (see
  `stability_math.characteristic_roots`). The one-sided reflex ``(v)+``, the activation/
  deactivation rates and the force-velocity curve have kinks at rest; central differences give
  their mean slopes, the describing function of a symmetric oscillation. A real (non-oscillating)
  mode keeps every kink on one side, so each direction (flexion, extension) is re-linearised
  slightly displaced along its rightmost real trunk mode until mode and kinks agree, whatever the
  central root: that is the rate at which a small perturbation to that side grows or decays in a
  simulation (a one-sided mode can run away while the central pair oscillates and decays). A real
  root crosses zero where the delay drops out of the characteristic equation (exp(0) = 1), so the
  critical delay is the central linearisation's. Where
  position reflexes sit at their set point (l_d = "neutral") the rate depends on the amplitude and
  the report says so.
* **Critical values**: the interval of co-activation level, uniform scale of the reflex gains and
  bushing stiffness (each with the others held) over which that margin is negative: around the
  present value when that is stable, else the first stable interval of a scan from the lower end;
  bounds by bisection, at the posture's rest state. The critical reflex delay when stable.
"""

from __future__ import annotations

import dataclasses
import functools
import time
import warnings
from dataclasses import dataclass, field

import numpy as np
from pydrake.systems.analysis import ResetIntegratorFromFlags, Simulator
from threadpoolctl import ThreadpoolController

from trunk_drake.diagram import TrunkOptions, build_trunk_diagram, release, rotation_coordinates
from trunk_drake.gap.linear import time_derivatives
from trunk_drake.muscle import thelen
from trunk_drake.optim.stability_math import (
    CriticalValue, StaticStability, characteristic_roots, critical_value, static_stability, unit_shape,
)
from trunk_drake.systems.muscles import muscle_parameters

JACOBIAN_STEP = 1e-7
DISPLACEMENT = 1e-4  # rad (0.006 deg, largest level): how far along a real mode its kinks are resolved
TRUNK_MODE_FRACTION = 1e-4  # a mode whose coordinates move less than this fraction of its largest state is no trunk mode
#   (a trunk mode's share is 0.006-1 on the default passenger; 1e-5 was seen on a mode of the activations alone)
BRANCH_STEP = 1e-9  # finite-difference step there, far below the displaced kink arguments
BRANCH_ITERATIONS = 6
EQUILIBRIUM_TOLERANCE = 1e-9  # Nm: Newton stops below this unbalanced generalized force
EQUILIBRIUM_ACCEPTED = 1e-6  # Nm: an equilibrium counts as found below this
MAX_EQUILIBRIUM_SHIFT = 0.35  # rad (20 deg): farther, the posture is not "near" an equilibrium
REAL_TOLERANCE = 1e-6
THRESHOLD_DEG = 0.1  # a position reflex whose set point is within this rotation of every level is "at threshold"
RANGES = {"coactivation": (0.01, 0.3), "reflex_gain_scale": (0.0, 20.0), "stiffness": (1.0, 3000.0)}
CRITICAL_RTOL = 0.02
DELAY_RANGE = (0.0, 0.3)  # s, searched for the critical delay


@dataclass
class DynamicStability:
    """Characteristic roots of the closed loop about the operating point."""

    coordinates: list[str]
    roots: np.ndarray  # rightmost first (1/s), central-difference linearisation
    delay: float
    branches: dict  # "central" / "flexion" / "extension" -> rightmost root (1/s) of that linearisation
    mode: np.ndarray  # least-stable mode over the coordinates (shape, largest entry +1; a one-sided branch's -1 where
    #   that turns it to its side: flexion-extension coordinates summing positive for flexion, negative for extension)
    mode_branch: str
    critical_delay: float | None
    reflexes: dict  # per group: muscles with a position reflex, engaged at rest, mean l_n - l_d
    method: str

    @property
    def margin(self) -> float:
        """Largest real part of the rightmost roots over all branches (1/s): < 0 stable."""
        return float(max(np.real(list(self.branches.values()))))

    @property
    def stable(self) -> bool:
        return self.margin < 0.0

    @property
    def rightmost(self) -> complex:
        return complex(self.branches[self.mode_branch])

    def summary(self) -> dict:
        s = self.rightmost
        return {"stable": self.stable, "margin_per_s": self.margin,
                "rightmost_root": {"real_per_s": s.real, "imag_rad_per_s": s.imag, "frequency_hz": abs(s.imag) / (2 * np.pi),
                                   "branch": self.mode_branch,
                                   "time_to_double_s": float(np.log(2) / s.real) if s.real > 0 else None,
                                   "time_to_halve_s": float(np.log(2) / -s.real) if s.real < 0 else None},
                "branches_per_s": {k: _complex_json(v) for k, v in self.branches.items()},
                "least_stable_mode": dict(zip(self.coordinates, self.mode.tolist())),
                "roots_per_s": [_complex_json(r) for r in self.roots[:12]],
                "delay_s": self.delay, "critical_delay_s": self.critical_delay,
                "reflexes": self.reflexes, "method": self.method}


@dataclass
class StabilityResult:
    """Static and dynamic stability of one posture of one configuration, and what would stabilise it."""

    coordinates: list[str]
    posture: np.ndarray  # requested (rad)
    equilibrium: np.ndarray  # nearest closed-loop rest posture (rad)
    equilibrium_found: bool | None  # None: no dynamic diagram (static analysis only)
    unbalanced: np.ndarray | None  # generalized force (Nm) left unbalanced at the requested posture
    static: StaticStability
    dynamic: DynamicStability | None
    critical: list[CriticalValue]
    options: dict
    wall_time_s: float
    metadata: dict = field(default_factory=dict)

    @property
    def stable(self) -> bool:
        return self.dynamic.stable if self.dynamic is not None else self.static.stable

    def summary(self) -> dict:
        shift = np.degrees(self.equilibrium - self.posture)
        return {
            "stable": self.stable,
            "verdict": self.verdict(),
            "operating_point": {
                "coordinates": self.coordinates, "posture_deg": np.degrees(self.posture).tolist(),
                "equilibrium_found": self.equilibrium_found, "equilibrium_deg": np.degrees(self.equilibrium).tolist(),
                "equilibrium_shift_deg": shift.tolist(),
                "unbalanced_at_posture_nm": None if self.unbalanced is None else dict(zip(self.coordinates, self.unbalanced.tolist()))},
            "static": self.static.summary(),
            "dynamic": None if self.dynamic is None else self.dynamic.summary(),
            "critical": {c.name: c.summary() for c in self.critical},
            "wall_time_s": self.wall_time_s, "options": self.options, "metadata": self.metadata,
        }

    def verdict(self) -> list[str]:
        """Plain sentences: stable or not, margin, mode, and what would make it stable."""
        lines = []
        st = self.static
        lines.append(f"static: {'stable' if st.stable else 'unstable'}, stability index {st.stability_index:+.1f} Nm/rad "
                     f"(least-stable mode {_shape_text(self.coordinates, st.least_stable_mode)})")
        if self.dynamic is not None:
            d = self.dynamic
            s = d.rightmost
            kind = (f"oscillating at {abs(s.imag) / (2 * np.pi):.2f} Hz" if not _is_real(s)
                    else f"non-oscillating, {d.mode_branch}")
            rate = (f"grows x2 every {np.log(2) / s.real:.3g} s" if s.real > 0 else f"decays /2 every {np.log(2) / -s.real:.3g} s")
            lines.append(f"dynamic: {'stable' if d.stable else 'unstable'}, margin {d.margin:+.3g} 1/s ({kind}; {rate}; "
                         f"mode {_shape_text(self.coordinates, d.mode)})")
            c = d.branches["central"]
            if d.mode_branch != "central" and not _is_real(c):
                lines.append(f"oscillation (central linearisation): root {c.real:+.3g} +- {abs(c.imag):.3g}i 1/s, natural "
                             f"frequency {abs(c) / (2 * np.pi):.2f} Hz, damping ratio {-c.real / abs(c):.2f}")
            if d.critical_delay is not None:
                lines.append(f"critical reflex delay: {d.critical_delay * 1e3:.1f} ms")
            at_threshold = sum(g["at_threshold"] for g in d.reflexes.values())
            if at_threshold:
                lines.append(f"caution: {at_threshold} position reflexes have their set point within a {THRESHOLD_DEG:g} deg "
                             "rotation of the rest length, so they switch on or off during a small perturbation: its growth "
                             "rate then depends on its amplitude and the linearisation may not predict it")
        if self.equilibrium_found is None:
            lines.append(f"no dynamic analysis: the {self.metadata.get('model', {}).get('dofs', '')} configuration has no dynamic diagram")
        elif not self.equilibrium_found:
            lines.append("no closed-loop equilibrium near the posture: the linearisation is about the posture itself")
        for c in self.critical:
            lines.append(("stable for " if c.value is not None else "") + c.summary()["text"])
        return lines


def stability(model, options: TrunkOptions | None = None, q=None, critical: bool = True, ranges: dict | None = None) -> StabilityResult:
    """Stability of posture `q` (default upright; `model.coordinates` order) of the trunk diagram with
    `options` (see module docstring). ``critical=False`` skips the bisections; `ranges` overrides
    RANGES (name -> (low, high)) for them."""
    start = time.perf_counter()
    opts = options or TrunkOptions()
    options_json = {k: v for k, v in dataclasses.asdict(opts).items() if k not in ("feedforward", "constants", "muscle_mask")}
    from trunk_drake.metadata import run_metadata

    if model.dofs == "spine3d":  # no dynamic diagram: the static analysis at the requested posture
        posture = np.zeros(len(model.coordinates)) if q is None else model.check_q(q)
        static = static_analysis(model, opts, posture, rest_activations(model, opts, posture))
        return StabilityResult(list(model.coordinates), posture, posture, None, None, static, None, [],
                               options_json, time.perf_counter() - start, run_metadata(model))
    loop = ClosedLoop(model, opts)
    try:
        posture = loop.posture(q)
        x_eq, found, unbalanced = loop.equilibrium(posture)
        static = loop.static(x_eq)
        dynamic = loop.dynamic(x_eq)
        found_critical = loop.critical_values({**RANGES, **(ranges or {})}, posture) if critical else []
    finally:
        release(loop.td.diagram)
    return StabilityResult(loop.coordinates, posture, loop.q_of(x_eq), found, unbalanced, static, dynamic, found_critical,
                           options_json, time.perf_counter() - start, run_metadata(model))


class ClosedLoop:
    """A built trunk diagram (no perturbation: pelvis fixed) prepared for stability analysis."""

    def __init__(self, model, options: TrunkOptions):
        if options.tendon != "rigid":
            raise ValueError("stability analysis supports rigid tendons only (tendon='rigid')")
        if (options.gto_gain and options.reflex_delay > 0) or (options.vestibular_gain and options.vestibular_delay > 0):
            raise ValueError("stability analysis models the delayed stretch reflex only; delayed Golgi or trunk-in-space "
                             "feedback is not supported (set their gains or delays to 0)")
        self.model, self.options = model, options
        self.td = build_trunk_diagram(model, dataclasses.replace(options, reflex_delay=0.0))
        self.delay = float(options.reflex_delay)
        self.base = self.td.model
        self.coordinates = list(self.base.coordinates)
        plant = self.td.plant
        self.nq, self.nv = plant.num_positions(), plant.num_velocities()
        self.n = self.td.muscles.n
        self.context = self.td.diagram.CreateDefaultContext()
        self.plant_context = plant.GetMyMutableContextFromRoot(self.context)
        self.muscle_context = self.td.muscles.GetMyMutableContextFromRoot(self.context)
        self.activations = slice(self.nq + self.nv, self.nq + self.nv + self.n)
        self.fe = rotation_coordinates(self.base)
        self.params = muscle_parameters(self.base, options.strength_scale)
        self._kp, self._kv = self.td.reflex.kp.copy(), self.td.reflex.kv.copy()
        self._k = self.td.bushings.k.copy()

    # ---- states ------------------------------------------------------------------
    def posture(self, q) -> np.ndarray:
        """Requested posture in this diagram's coordinates (zeros: upright)."""
        if q is None:
            return np.zeros(self.nq)
        q = self.model.check_q(q)
        names = self.model.coordinates
        missing = [c for c in self.coordinates if c not in names]
        if missing:
            raise ValueError(f"posture q lacks coordinates {missing}")
        return np.array([q[names.index(c)] for c in self.coordinates])

    def q_of(self, x) -> np.ndarray:
        return np.asarray(x[: self.nq], float).copy()

    def rest_state(self, q) -> np.ndarray:
        """Root state at posture q at rest: v = 0, activation = steady excitation, muscles steady."""
        plant = self.td.plant
        plant.SetPositions(self.plant_context, q)
        plant.SetVelocities(self.plant_context, np.zeros(self.nv))
        path = self.td.paths.GetOutputPort("path_state").Eval(self.td.paths.GetMyContextFromRoot(self.context))
        mixer = self.td.diagram.GetSubsystemByName("excitation")
        u = mixer.GetOutputPort("excitation").Eval(mixer.GetMyContextFromRoot(self.context))
        a = thelen.clamp_activation(u, self.options.constants)
        self.muscle_context.SetContinuousState(self.td.muscles.steady_state(a, path))
        x = self.context.get_continuous_state_vector().CopyToVector()
        assert np.allclose(x[: self.nq], q) and np.allclose(x[self.activations], a), "unexpected diagram state layout"
        return x

    def generalized_force(self, x) -> np.ndarray:
        """Net generalized force at rest state x (Nm): M vdot."""
        vdot = time_derivatives(self.td, self.context, x)[self.nq: self.nq + self.nv]
        return self.td.plant.CalcMassMatrix(self.plant_context) @ vdot

    def rotation_from(self, x0, times, integrator: str = "radau3", accuracy: float = 1e-4) -> np.ndarray:
        """Lumbar rotation (the flexion-extension coordinates summed) at `times` of the full nonlinear diagram (the
        loop's, without a reflex delay) started at state x0: what a linearised rate is checked against."""
        simulator = Simulator(self.td.diagram)
        ResetIntegratorFromFlags(simulator, integrator, 0.005)
        simulator.get_mutable_integrator().set_target_accuracy(accuracy)
        context = simulator.get_mutable_context()
        context.SetContinuousState(np.asarray(x0, float))
        simulator.Initialize()
        out = []
        for t in times:
            simulator.AdvanceTo(t)
            out.append(context.get_continuous_state_vector().CopyToVector()[self.fe].sum())
        return np.array(out)

    def equilibrium(self, posture, max_iter: int = 30):
        """(rest state at the equilibrium nearest `posture`, found?, unbalanced force at the posture)."""
        unbalanced = self.generalized_force(self.rest_state(posture))
        q, g = posture.copy(), unbalanced
        h = 1e-7
        for _ in range(max_iter):
            if np.max(np.abs(g)) < EQUILIBRIUM_TOLERANCE:
                break
            J = np.column_stack([(self.generalized_force(self.rest_state(q + h * e))
                                  - self.generalized_force(self.rest_state(q - h * e))) / (2 * h) for e in np.eye(self.nq)])
            q = q + np.linalg.lstsq(J, -g, rcond=None)[0]
            g = self.generalized_force(self.rest_state(q))
            if np.max(np.abs(q - posture)) > MAX_EQUILIBRIUM_SHIFT or not np.all(np.isfinite(q)):
                return self.rest_state(posture), False, unbalanced
        found = np.max(np.abs(self.generalized_force(self.rest_state(q)))) < EQUILIBRIUM_ACCEPTED
        return self.rest_state(q if found else posture), bool(found), unbalanced

    # ---- static ------------------------------------------------------------------
    def static(self, x) -> StaticStability:
        """Energy Hessian at rest state x (activations held)."""
        return static_analysis(self.base, self.options, self.q_of(x), x[self.activations], self.params)

    # ---- dynamic -----------------------------------------------------------------
    def jacobian(self, x, h: float = JACOBIAN_STEP) -> np.ndarray:
        """d(x')/dx of the diagram at x by central differences of its time derivatives: the plant's
        q and v columns one at a time; the muscle-local states (activations, SRS references), each of
        which acts only on its own muscle's rates and tendon force, a whole block per evaluation, the
        tendon-force change mapped to accelerations by M^-1 R^T (as the diagram does).
        Equals `gap.linear.state_jacobian` (tested) at about 1/15 of the evaluations."""
        x = np.asarray(x, float)
        nx, npl = x.size, self.nq + self.nv
        A = np.zeros((nx, nx))
        for j in range(npl):
            dx = np.zeros(nx)
            dx[j] = h
            A[:, j] = (time_derivatives(self.td, self.context, x + dx) - time_derivatives(self.td, self.context, x - dx)) / (2 * h)
        force_port = self.td.muscles.GetOutputPort("tendon_force")
        for start in range(npl, nx, self.n):
            block = slice(start, start + self.n)
            dx = np.zeros(nx)
            dx[block] = h
            plus = time_derivatives(self.td, self.context, x + dx)
            force_plus = force_port.Eval(self.muscle_context).copy()
            minus = time_derivatives(self.td, self.context, x - dx)
            force_minus = force_port.Eval(self.muscle_context)
            rates = (plus - minus)[npl:] / (2 * h)
            for row in range(npl, nx, self.n):
                A[row: row + self.n, block] = np.diag(rates[row - npl: row - npl + self.n])
            dforce = (force_plus - force_minus) / (2 * h)
            self.context.SetContinuousState(x)
            path = self.td.paths.GetOutputPort("path_state").Eval(self.td.paths.GetMyContextFromRoot(self.context))
            m_inv = np.linalg.inv(self.td.plant.CalcMassMatrix(self.plant_context))
            A[self.nq: npl, block] = m_inv @ (path.moment_arms.T * dforce)
        self.context.SetContinuousState(x)
        return A

    def split(self, A):
        """(A0, A1): A1 = the stretch reflex (activation rates' dependence on q and v), delayed."""
        A1 = np.zeros_like(A)
        cols = slice(0, self.nq + self.nv)
        A1[self.activations, cols] = A[self.activations, cols]
        return A - A1, A1

    def rightmost(self, x, delay=None, h=JACOBIAN_STEP):
        """Characteristic roots and vectors of the linearisation at x."""
        A0, A1 = self.split(self.jacobian(x, h))
        with single_threaded_blas():
            return characteristic_roots(A0, A1, self.delay if delay is None else delay)

    def branch(self, x, value, vector):
        """The real root `value` (with mode `vector`) re-linearised with its kinks resolved along the
        mode, until mode and kinks agree: (root, mode). Each step takes the rightmost real trunk mode
        of the displaced linearisation (a Newton step from the previous root can land on a
        neighbouring root, or on a mode no coordinate takes part in, and so miss a growing one), turned to
        the side `vector` starts on (the sum of its flexion-extension coordinates keeps its sign). Two steps
        at least: the first starts from `vector`, whose kinks may still be at their mean slopes. Near a
        critical value some kinks flip with every step and the roots wander about the simulated rate, now and
        then far off; then the median of the roots after the first step's."""
        d, value, seen = np.real(vector), float(np.real(value)), []
        side = np.sign(d[self.fe].sum()) or 1.0
        for step in range(BRANCH_ITERATIONS):
            d = d / np.max(np.abs(d[: self.nq]))
            A0, A1 = self.split(self.jacobian(x + DISPLACEMENT * d, BRANCH_STEP))
            with single_threaded_blas():
                roots, vectors = characteristic_roots(A0, A1, self.delay)
            k = self._rightmost_real_trunk_mode(roots, vectors)
            if k is None:
                return complex(value), d  # only oscillating trunk modes on this side: keep the last real one
            new = np.real(vectors[:, k])
            new = new if side * new[self.fe].sum() > 0 else -new
            converged = step > 0 and abs(roots[k].real - value) <= 1e-3 * abs(roots[k].real) + 1e-9
            value, d = float(roots[k].real), new
            seen.append(value)
            if converged:
                return complex(value), d
        return complex(float(np.median(seen[1:]))), d

    def _rightmost_real_trunk_mode(self, roots, vectors) -> int | None:
        """Index of the rightmost real root whose mode turns the trunk (its flexion-extension coordinates sum to
        at least TRUNK_MODE_FRACTION of its largest state), else None."""
        for k, (root, v) in enumerate(zip(roots, vectors.T)):
            if _is_real(root) and abs(np.real(v[self.fe]).sum()) > TRUNK_MODE_FRACTION * np.max(np.abs(v)):
                return k
        return None

    def one_sided_margin(self, x, until_unstable: bool = False) -> tuple[np.ndarray, dict, dict]:
        """Roots of the central linearisation, its rightmost root, and each direction's one-sided branch,
        whatever the central root: a trunk displaced to one side can run away without oscillating where the
        central linearisation's rightmost pair oscillates. Each branch starts from the least-stable trunk
        mode (an oscillating one: its shape over the coordinates, the other states at rest): (roots, {branch: root},
        {branch: mode over the coordinates})."""
        roots, vectors = self.rightmost(x)
        branches = {"central": complex(roots[0])}
        modes = {"central": vectors[: self.nq, 0]}
        trunk = next((k for k, v in enumerate(vectors.T)
                      if np.max(np.abs(v[: self.nq])) > TRUNK_MODE_FRACTION * np.max(np.abs(v))), None)
        if trunk is not None and not (until_unstable and roots[0].real >= 0):
            if _is_real(roots[trunk]):
                seed = np.real(vectors[:, trunk]) / np.max(np.abs(np.real(vectors[: self.nq, trunk])))
            else:  # an oscillating mode has no one real shape over the other states: the coordinates alone
                seed = np.zeros(len(x))
                seed[: self.nq] = unit_shape(vectors[: self.nq, trunk])
            flexion = np.sign(seed[self.fe].sum()) or 1.0
            for name, sign in (("flexion", flexion), ("extension", -flexion)):
                value, shape = self.branch(x, roots[trunk], sign * seed)
                branches[name], modes[name] = value, shape[: self.nq]
                if until_unstable and value.real >= 0:
                    break
        return roots, branches, modes

    def dynamic(self, x, delay_search: bool = True) -> DynamicStability:
        roots, branches, modes = self.one_sided_margin(x)
        method = ("characteristic roots of the central-difference linearisation of the diagram"
                  + (f"; reflex delay {self.delay * 1e3:.1f} ms: Chebyshev spectral discretisation + Newton on the exact "
                     "characteristic equation" if self.delay > 0 else "")
                  + ("; each direction re-linearised along its rightmost real trunk mode (kinks one-sided)"
                     if len(branches) > 1 else ""))
        branch = max(branches, key=lambda k: branches[k].real)
        mode = unit_shape(modes[branch])
        if branch != "central" and (mode[self.fe].sum() > 0) != (branch == "flexion"):
            mode = -mode  # a one-sided mode keeps its side (an extension mode's flexion-extension sum is negative)
        result = DynamicStability(self.coordinates, roots, self.delay, branches, mode, branch,
                                  None, self.reflexes(x), method)
        if result.stable and delay_search:
            result.critical_delay = self.critical_delay(x)
        return result

    def critical_delay(self, x) -> float | None:
        """Smallest reflex delay in DELAY_RANGE at which the central-difference linearisation is unstable."""
        A0, A1 = self.split(self.jacobian(x))
        if not np.any(A1):
            return None

        def unstable(tau):
            with single_threaded_blas():
                return characteristic_roots(A0, A1, tau)[0][0].real >= 0

        grid = np.linspace(max(self.delay, DELAY_RANGE[0]), DELAY_RANGE[1], 13)
        first = next((k for k, tau in enumerate(grid) if unstable(tau)), None)
        if first is None:
            return None
        lo, hi = grid[max(0, first - 1)], grid[first]
        while hi - lo > 1e-4:
            mid = 0.5 * (lo + hi)
            lo, hi = (lo, mid) if unstable(mid) else (mid, hi)
        return float(hi)

    def reflexes(self, x) -> dict:
        """Per group: muscles with a position reflex (kp > 0), those engaged at rest (l_n > l_d), those
        whose set point lies within the fiber excursion of a THRESHOLD_DEG rotation of every level (there
        the reflex switches within a small perturbation: the margin depends on its amplitude), mean l_n - l_d."""
        self.context.SetContinuousState(x)
        ln = self.td.muscles.GetOutputPort("normalized_fiber_length").Eval(self.muscle_context)
        stretch = ln - self.td.reflex.l_desired
        path = self.td.paths.GetOutputPort("path_state").Eval(self.td.paths.GetMyContextFromRoot(self.context))
        excursion = np.radians(THRESHOLD_DEG) * np.abs(path.moment_arms).sum(axis=1) / self.params.optimal_fiber_length
        out = {}
        index = {m: i for i, m in enumerate(self.base.muscles)}
        for group, members in self.base.groups.items():
            idx = np.array([index[m] for m in members])
            with_kp = idx[self.td.reflex.kp[idx] > 0]
            engaged = with_kp[stretch[with_kp] > 0]
            out[group] = {"muscles": int(len(idx)), "with_position_reflex": int(len(with_kp)), "engaged_at_rest": int(len(engaged)),
                          "at_threshold": int(np.sum(np.abs(stretch[with_kp]) < excursion[with_kp])),
                          "mean_stretch_beyond_set_point": float(stretch[idx].mean()),
                          "engaged": [self.base.muscles[i] for i in engaged]}
        return out

    # ---- critical values -----------------------------------------------------------
    def _margin_with(self, posture, feedforward=None, gain_scale=1.0, stiffness=None) -> float:
        """Margin (over the one-sided branches, as `dynamic` reports it) at the rest state of `posture` with
        one change, restored after. The rest state, not the nearest equilibrium: near a critical value that
        equilibrium runs away from the posture (its stiffness matrix turns singular)."""
        source = self.td.diagram.GetSubsystemByName("feedforward")
        base_ff = source.get_source_value(source.GetMyContextFromRoot(self.context)).CopyToVector()
        reflex, bushings = self.td.reflex, self.td.bushings
        try:
            if feedforward is not None:
                source.get_mutable_source_value(source.GetMyMutableContextFromRoot(self.context)).SetFromVector(feedforward)
            reflex.kp, reflex.kv = self._kp * gain_scale, self._kv * gain_scale
            if stiffness is not None:
                bushings.k = np.full_like(self._k, stiffness)
            x = self.rest_state(posture)
            return max(r.real for r in self.one_sided_margin(x, until_unstable=True)[1].values())
        finally:
            source.get_mutable_source_value(source.GetMyMutableContextFromRoot(self.context)).SetFromVector(base_ff)
            reflex.kp, reflex.kv, bushings.k = self._kp.copy(), self._kv.copy(), self._k.copy()

    def critical_values(self, ranges: dict, posture) -> list[CriticalValue]:
        from trunk_drake.optim.static import coactivation

        def coactivated(level):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                return self._margin_with(posture, feedforward=coactivation(self.base, level))

        uniform = np.ptp(self._k) == 0
        searches = [("co-activation (minimum activation)", coactivated, ranges["coactivation"], "", True, None)]
        if np.any(self._kp) or np.any(self._kv):
            searches.append(("reflex gain scale", lambda s: self._margin_with(posture, gain_scale=s),
                             ranges["reflex_gain_scale"], "x", False, 1.0))
        searches.append(("bushing stiffness", lambda k: self._margin_with(posture, stiffness=k), ranges["stiffness"], "Nm/rad", True,
                         float(self._k[0]) if uniform else None))
        return [critical_value(name, margin, low, high, unit=unit, rtol=CRITICAL_RTOL, log=log, current=current)
                for name, margin, (low, high), unit, log, current in searches]


def static_analysis(model, options: TrunkOptions, q, activations, params=None) -> StaticStability:
    """Energy Hessian of `model` (any configuration) at posture q with `activations` held."""
    q, a = np.asarray(q, float), np.asarray(activations, float)
    params = params or muscle_parameters(model, options.strength_scale)
    constants = options.constants
    path = model.path_state(q, np.zeros(len(q)))
    mask = np.ones(model.n_muscles) if options.muscle_mask is None else np.asarray(options.muscle_mask, float)
    force = thelen.rigid_tendon(a, path.lengths, path.velocities, params, constants).tendon_force * mask
    slope = thelen.rigid_tendon_derivatives(a, path.lengths, path.velocities, params, constants).d_length * mask
    L = model.level_matrix  # the bushings act on the level angles (coupled in the rhythm)
    angles = L @ q
    level_stiffness = np.broadcast_to(np.asarray(options.stiffness, float), (len(L),)) * (1.0 + 3.0 * options.cubic * angles**2)
    bushing = L.T @ (level_stiffness[:, None] * L)
    srs = None
    if options.srs is not None:
        kin = thelen.rigid_kinematics(path.lengths, path.velocities, params, constants)
        srs = mask * np.where(kin.clamped, 0.0, options.srs.path_stiffness(
            thelen.clamp_activation(a, constants), kin.active_force_length, params.max_isometric_force,
            params.optimal_fiber_length, kin.cos_pennation))
    return static_stability(model.coordinates, gravity_hessian(model.plant, model.plant.CreateDefaultContext(), q), bushing,
                            force, length_hessian(model, q), path.moment_arms, slope, srs)


def rest_activations(model, options: TrunkOptions, q) -> np.ndarray:
    """Steady activations at posture q without a diagram: feed-forward plus the stretch-reflex tone."""
    from trunk_drake.diagram import _desired_length
    from trunk_drake.systems.reflex import StretchReflex

    params = muscle_parameters(model, options.strength_scale)
    path = model.path_state(q, np.zeros(len(q)))
    ln = thelen.rigid_kinematics(path.lengths, path.velocities, params, options.constants).normalized_fiber_length
    reflex = StretchReflex(model.n_muscles, options.per_muscle(model, options.kp), options.per_muscle(model, options.kv),
                           _desired_length(model, options, params))
    ff = options.feedforward if options.feedforward is not None else np.full(model.n_muscles, options.constants.minimum_activation)
    return thelen.clamp_activation(np.asarray(ff, float) + reflex.feedback(ln, np.zeros(model.n_muscles)), options.constants)


def gravity_hessian(plant, context, q, h: float = 1e-6) -> np.ndarray:
    """Hessian of the gravitational potential, -d(gravity generalized force)/dq, by central differences."""
    def gravity(qq):
        plant.SetPositions(context, qq)
        return plant.CalcGravityGeneralizedForces(context)

    q = np.asarray(q, float)
    return -np.column_stack([(gravity(q + h * e) - gravity(q - h * e)) / (2 * h) for e in np.eye(q.size)])


def length_hessian(model, q, h: float = 1e-6) -> np.ndarray:
    """d2L/dq2 of every musculotendon path (n_muscles, n, n): central differences of the analytic
    moment arms -dL/dq, symmetrised."""
    q = np.asarray(q, float)
    hess = -np.stack([(model.path_state(q + h * e).moment_arms - model.path_state(q - h * e).moment_arms) / (2 * h)
                      for e in np.eye(q.size)], axis=2)
    return 0.5 * (hess + hess.transpose(0, 2, 1))


@functools.cache
def _blas_controller() -> ThreadpoolController:
    return ThreadpoolController()  # finds the BLAS libraries once (a scan costs ~10 ms)


def single_threaded_blas():
    """Context: one BLAS thread. Multi-threaded LAPACK is 10-20x slower on these sizes on a loaded machine."""
    return _blas_controller().limit(limits=1)


def _is_real(root) -> bool:
    """A characteristic root whose imaginary part is negligible (REAL_TOLERANCE, relative above 1 1/s)."""
    return abs(root.imag) <= REAL_TOLERANCE * max(1.0, abs(root.real))


def _complex_json(value) -> dict:
    value = complex(value)
    return {"real": value.real, "imag": value.imag}


def _shape_text(coordinates, shape) -> str:
    return ", ".join(f"{c} {v:+.2f}" for c, v in zip(coordinates, shape))
