"""OpenSim 4.6 as an oracle for .osim files read by trunk-drake (test helper; needs `opensim`).

`OsimOracle` loads a file with OpenSim, optionally with its coordinate couplers switched off,
sets coordinate values and returns OpenSim's musculotendon lengths, moment arms, mass, centre
of mass and Thelen tendon forces. Moment arms are the generalized forces of a unit tension:
OpenSim's own point-force directions of each path (`getPointForceDirections`) through Simbody's
station Jacobians, all coordinates at once; with couplers, the coupling vector of each
independent coordinate (as OpenSim's MomentArmSolver uses) from the file's coupler functions.
`check_against_compute_moment_arm` confirms this equals `computeMomentArm` at the current pose.
"""

from __future__ import annotations

import numpy as np
import opensim as osim

from trunk_drake.muscle import thelen as th


def _scale(coupler) -> float:
    return float(coupler.getPropertyByName("scale_factor").toString())


class OsimOracle:
    def __init__(self, path, couplers: bool):
        osim.Logger.setLevelString("error")
        self.model = osim.Model(str(path))
        self.constraints = self.model.getConstraintSet()
        for i in range(self.constraints.getSize()):
            self.constraints.get(i).set_isEnforced(couplers)
        self.state = self.model.initSystem()
        self.coords = self.model.getCoordinateSet()
        self.names = [self.coords.get(i).getName() for i in range(self.coords.getSize())]
        self.muscles = self.model.getMuscles()
        self.muscle_names = [self.muscles.get(i).getName() for i in range(self.muscles.getSize())]
        self.thelen = [osim.Thelen2003Muscle.safeDownCast(self.muscles.get(i)) for i in range(self.muscles.getSize())]
        self.couplers = []  # (dependent, independent, function, scale)
        if couplers:
            for i in range(self.constraints.getSize()):
                c = osim.CoordinateCouplerConstraint.safeDownCast(self.constraints.get(i))
                if c is not None:
                    self.couplers.append((c.getDependentCoordinateName(), c.getIndependentCoordinateNames().get(0),
                                          c.getFunction(), _scale(c)))
        self.dependent = {d for d, _, _, _ in self.couplers}

    # ---- poses -----------------------------------------------------------------------------
    def sample(self, rng) -> dict[str, float]:
        """Random values within the coordinate ranges (independent ones; dependents from couplers)."""
        values = {}
        for name in self.names:
            c = self.coords.get(name)
            lo, hi = c.getRangeMin(), c.getRangeMax()
            if c.getDefaultLocked() or name in self.dependent:
                values[name] = c.getDefaultValue()
                continue
            if hi - lo > 2 * np.pi:  # "unbounded" in the file: the range its coupler gives it
                lo, hi = self._coupled_range(name)
            values[name] = rng.uniform(lo, hi)
        return self.with_couplers(values)

    def _coupled_range(self, name):
        for i in range(self.constraints.getSize()):  # switched off or not, the file's couplers are there
            c = osim.CoordinateCouplerConstraint.safeDownCast(self.constraints.get(i))
            if c is not None and c.getDependentCoordinateName() == name:
                ind = self.coords.get(c.getIndependentCoordinateNames().get(0))
                x = np.linspace(ind.getRangeMin(), ind.getRangeMax(), 101)
                y = [_scale(c) * c.getFunction().calcValue(osim.Vector(1, float(v))) for v in x]
                return min(y), max(y)
        raise AssertionError(f"coordinate {name} has no finite range and no coupler")

    def with_couplers(self, values):
        for _ in range(len(self.couplers)):
            for dep, ind, f, scale in self.couplers:
                values[dep] = scale * f.calcValue(osim.Vector(1, float(values[ind])))
        return values

    def coupling(self, values, independent: str) -> np.ndarray:
        """d(coordinates)/d(independent) along the couplers (OpenSim's normalised coupling vector)."""
        out = np.zeros(len(self.names))
        out[self.names.index(independent)] = 1.0
        for _ in range(len(self.couplers)):
            for dep, ind, f, scale in self.couplers:
                slope = scale * f.calcDerivative(osim.StdVectorInt([0]), osim.Vector(1, float(values[ind])))
                out[self.names.index(dep)] = slope * out[self.names.index(ind)]
        return out

    def set(self, values: dict[str, float]):
        for name, v in values.items():
            c = self.coords.get(name)
            c.setLocked(self.state, False)
            c.setValue(self.state, float(v), False)
        self.model.realizePosition(self.state)

    # ---- outputs -----------------------------------------------------------------------------
    def lengths(self) -> np.ndarray:
        return np.array([self.muscles.get(i).getLength(self.state) for i in range(self.muscles.getSize())])

    def generalized_forces(self) -> np.ndarray:
        """(n_muscles, n_coordinates): generalized force of a unit tension (coupling-free moment arms)."""
        matter = self.model.getMatterSubsystem()
        out = np.zeros((self.muscles.getSize(), self.state.getNU()))
        f = osim.Vector()
        for i in range(self.muscles.getSize()):
            pfds = osim.ArrayPointForceDirection()
            self.muscles.get(i).getGeometryPath().getPointForceDirections(self.state, pfds)
            for k in range(pfds.getSize()):
                p = pfds.get(k)
                matter.multiplyByStationJacobianTranspose(self.state, p.frame().getMobilizedBodyIndex(), p.point(),
                                                          p.direction(), f)
                out[i] += np.array([f.get(j) for j in range(f.size())])
        return out

    def compute_moment_arm(self, coordinate: str) -> np.ndarray:
        c = self.coords.get(coordinate)
        return np.array([self.muscles.get(i).getGeometryPath().computeMomentArm(self.state, c)
                         for i in range(self.muscles.getSize())])

    def mass_and_com(self):
        return self.model.getTotalMass(self.state), np.array(self.model.calcMassCenterPosition(self.state).to_numpy())

    def tendon_forces(self, activation: np.ndarray, fiber_length: np.ndarray) -> np.ndarray:
        """OpenSim's Thelen tendon forces at the given activations and fiber lengths (path at rest)."""
        for i, m in enumerate(self.thelen):
            m.setActivation(self.state, float(activation[i]))
            m.setFiberLength(self.state, float(fiber_length[i]))
        self.model.realizeDynamics(self.state)
        return np.array([self.muscles.get(i).getTendonForce(self.state) for i in range(self.muscles.getSize())])

    def equilibrium_tendon_forces(self, activation: np.ndarray) -> np.ndarray:
        """Tendon forces at OpenSim's static fiber equilibrium (NaN where its solver fails)."""
        failed = []
        for i, m in enumerate(self.thelen):
            m.setActivation(self.state, float(activation[i]))
            try:
                m.computeInitialFiberEquilibrium(self.state)
            except RuntimeError:
                failed.append(i)
        self.model.realizeDynamics(self.state)
        out = np.array([self.muscles.get(i).getTendonForce(self.state) for i in range(self.muscles.getSize())])
        out[failed] = np.nan
        return out


def thelen_equilibrium(model, lengths, activation) -> th.MuscleState:
    """Our static fiber equilibrium with the file's Hill parameters and Thelen constants."""
    params = th.MuscleParameters(
        max_isometric_force=model.muscle_array("max_isometric_force"),
        optimal_fiber_length=model.muscle_array("optimal_fiber_length"),
        tendon_slack_length=model.muscle_array("tendon_slack_length"),
        pennation_angle_at_optimal=model.muscle_array("pennation_angle"),
    )
    constants = th.ThelenConstants(**model.spec.muscle_constants)
    return th.equilibrium_fiber_length(activation, lengths, params, constants)
