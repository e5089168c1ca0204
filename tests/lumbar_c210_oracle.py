"""Compare MyoTorso with the original OpenSim Lumbar_C_210 model (test oracle; needs `opensim`).

MyoTorso was converted from Christophy et al.'s Lumbar_C_210.osim. This module loads that
file with OpenSim, reads its musculotendon lengths at the neutral posture and its Thelen
parameters, and compares them with ours; for strength, it reads OpenSim's statics at the
upright posture (moment arms, muscle forces, gravity and load) with the couplers enforced (the
lumbar rhythm) or disabled. The .osim file itself is never copied.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from trunk_drake.model.architecture import derive_hill_lengths

@dataclass
class OsimMuscles:
    """Per-muscle values read from an .osim model (arrays in the order of `names`)."""

    names: list[str]
    neutral_length: np.ndarray
    optimal_fiber_length: np.ndarray
    tendon_slack_length: np.ndarray
    pennation_angle: np.ndarray
    max_isometric_force: np.ndarray


def read_osim_muscles(path: str) -> OsimMuscles:
    """Musculotendon lengths at the default (neutral) pose and Hill parameters, via OpenSim."""
    import opensim

    opensim.Logger.setLevelString("error")
    model = opensim.Model(str(path))
    state = model.initSystem()
    model.realizePosition(state)
    muscles = model.getMuscles()
    rows = [muscles.get(i) for i in range(muscles.getSize())]
    return OsimMuscles(
        names=[m.getName() for m in rows],
        neutral_length=np.array([m.getLength(state) for m in rows]),
        optimal_fiber_length=np.array([m.getOptimalFiberLength() for m in rows]),
        tendon_slack_length=np.array([m.getTendonSlackLength() for m in rows]),
        pennation_angle=np.array([m.getPennationAngleAtOptimalFiberLength() for m in rows]),
        max_isometric_force=np.array([m.getMaxIsometricForce() for m in rows]),
    )


@dataclass
class HillComparison:
    """Relative differences, ours vs the .osim, per muscle (model order)."""

    muscles: list[str]
    groups: list[str]
    neutral_length: np.ndarray
    optimal_fiber_length: np.ndarray
    tendon_slack_length: np.ndarray
    osim_follows_method: np.ndarray  # the .osim values equal the published method applied to OpenSim's own lengths (1 %)

    def by_group(self) -> dict[str, dict[str, float]]:
        """Largest relative difference per group: all muscles, and muscles whose .osim follows the method."""
        out = {}
        for g in dict.fromkeys(self.groups):
            sel = np.array([x == g for x in self.groups])
            follow = sel & self.osim_follows_method
            out[g] = {
                "n": int(sel.sum()),
                "neutral_length": float(self.neutral_length[sel].max()),
                "optimal_fiber_length": float(self.optimal_fiber_length[sel].max()),
                "tendon_slack_length": float(self.tendon_slack_length[sel].max()),
                "n_osim_follows_method": int(follow.sum()),
                "optimal_fiber_length_where_followed": float(self.optimal_fiber_length[follow].max()) if follow.any() else math.nan,
                "tendon_slack_length_where_followed": float(self.tendon_slack_length[follow].max()) if follow.any() else math.nan,
            }
        return out


def compare_hill_parameters(model, osim_path: str, tolerance: float = 0.01) -> HillComparison:
    """Our neutral lengths and derived Hill lengths against Lumbar_C_210.osim."""
    osim = read_osim_muscles(osim_path)
    index = {n: i for i, n in enumerate(osim.names)}
    missing = [n for n in model.muscles if n not in index]
    if missing:
        raise ValueError(f"{osim_path} lacks muscles {missing[:5]}... of the model")
    order = [index[n] for n in model.muscles]
    lmt = osim.neutral_length[order]
    ours_lmt = model.muscle_lengths(np.zeros(len(model.coordinates)))
    lopt = model.muscle_array("optimal_fiber_length")
    lslack = model.muscle_array("tendon_slack_length")
    # the published method applied to OpenSim's own neutral lengths
    method = derive_hill_lengths(model.muscles, lmt)
    o_lopt, o_lslack = osim.optimal_fiber_length[order], osim.tendon_slack_length[order]
    follows = (np.abs(method.optimal_fiber_length / o_lopt - 1) < tolerance) & (
        np.abs(method.tendon_slack_length / o_lslack - 1) < tolerance
    )
    return HillComparison(
        muscles=list(model.muscles),
        groups=[m.group for m in model.spec.muscles],
        neutral_length=np.abs(ours_lmt / lmt - 1),
        optimal_fiber_length=np.abs(lopt / o_lopt - 1),
        tendon_slack_length=np.abs(lslack / o_lslack - 1),
        osim_follows_method=follows,
    )


RHYTHM_COORDINATES = ("flex_extension",)  # Lumbar_C_210's independent flexion coordinate (couplers enforced)
LEVEL_COORDINATES = ("flex_extension", "L4_L5_FE", "L3_L4_FE", "L2_L3_FE", "L1_L2_FE")  # couplers disabled


@dataclass
class OsimStatics:
    """Lumbar_C_210 in OpenSim at the upright posture, in trunk-drake's static-optimisation terms.

    Coordinates are the .osim's, flexion positive (minus OpenSim's angle, which is positive in
    extension): with couplers enforced ``flex_extension`` is the lumbar rhythm (Lumbar_C_210's
    level slopes sum to 1: it is the sum of the level angles); with couplers disabled the five
    flexion coordinates are independent (``flex_extension`` then turns L5/S1 by 0.125 of itself) and
    every other coordinate (the Abdomen's, the wrap body's) stays at zero, as if locked.
    `moment_arms` (n_muscles, n_coordinates) are OpenSim's own ``Muscle.computeMomentArm``;
    `active` is OpenSim's ``calcInextensibleTendonActiveFiberForce`` at full activation (what its
    Static Optimization Tool uses); `passive` is the rigid-tendon passive fiber force along the
    tendon from the .osim's parameters and Thelen constants with trunk_drake.muscle.thelen
    (OpenSim's Thelen2003Muscle has no rigid-tendon mode to ask, and its tool ignores passive
    force); `gravity` is the generalized gravity force and `load_per_newton` the generalized force
    of a unit horizontal load at `points` (torso frame, equal shares) pushing along the pelvis'
    anterior ("extension") or posterior ("flexion") direction: ``M g . dc/dq`` for the centre of
    mass c and ``dp/dq . direction``, by central differences with OpenSim assembling the couplers
    (OpenSim's potential energy would include the muscles' elastic energy).
    """

    coordinates: tuple[str, ...]
    muscles: list[str]
    moment_arms: np.ndarray
    active: np.ndarray
    passive: np.ndarray
    max_isometric_force: np.ndarray
    gravity: np.ndarray
    load_per_newton: dict[str, np.ndarray]

    def balance(self, include_passive: bool = True):
        """The static-optimisation balance (trunk_drake.optim.static.MomentBalance) without load."""
        from trunk_drake.optim.static import MomentBalance

        passive = self.passive if include_passive else np.zeros_like(self.passive)
        return MomentBalance(self.moment_arms, self.active, passive, -self.gravity, self.coordinates, tuple(self.muscles))


def osim_statics(osim_path: str, points, couplers: bool = True, step: float = 1e-5) -> OsimStatics:
    """`OsimStatics` of the .osim upright, its couplers enforced (the rhythm) or disabled (independent levels)."""
    import opensim

    from trunk_drake.muscle import thelen

    opensim.Logger.setLevelString("error")
    model = opensim.Model(str(osim_path))
    constraints = model.getConstraintSet()
    for i in range(constraints.getSize()):
        constraints.get(i).set_isEnforced(couplers)
    state = model.initSystem()
    names = RHYTHM_COORDINATES if couplers else LEVEL_COORDINATES
    coords = [model.getCoordinateSet().get(n) for n in names]
    torso, sacrum = model.getBodySet().get("torso"), model.getBodySet().get("sacrum")

    def vec(v):
        return np.array([v.get(k) for k in range(3)])

    def at(j, flexion):
        """Centre of mass and load points with coordinate j at `flexion` (the others upright)."""
        for c in coords:
            c.setValue(state, 0.0, False)
        coords[j].setValue(state, -flexion, True)  # OpenSim assembles the coupled coordinates
        model.realizePosition(state)
        return vec(model.calcMassCenterPosition(state)), np.array(
            [vec(torso.findStationLocationInGround(state, opensim.Vec3(*p))) for p in points]).mean(axis=0)

    at(0, 0.0)
    model.realizeVelocity(state)
    g = vec(model.getGravity())
    weight = model.getTotalMass(state) * g
    up = -g / np.linalg.norm(g)
    R = sacrum.getTransformInGround(state).R()
    anterior = np.array([R.get(k, 0) for k in range(3)])
    anterior -= (anterior @ up) * up
    anterior /= np.linalg.norm(anterior)
    muscles = model.getMuscles()
    rows = [opensim.Thelen2003Muscle.safeDownCast(muscles.get(i)) for i in range(muscles.getSize())]
    arms = np.array([[-m.computeMomentArm(state, c) for c in coords] for m in rows])
    f_max = np.array([m.getMaxIsometricForce() for m in rows])
    active = np.array([m.calcInextensibleTendonActiveFiberForce(state, 1.0) for m in rows])
    params = thelen.MuscleParameters(f_max, [m.getOptimalFiberLength() for m in rows], [m.getTendonSlackLength() for m in rows],
                                     [m.getPennationAngleAtOptimalFiberLength() for m in rows])
    lengths = np.array([m.getLength(state) for m in rows])
    passive = thelen.rigid_tendon_force_split(lengths, np.zeros(len(rows)), params, _osim_constants(rows)).passive
    gravity, per_newton = np.zeros(len(coords)), np.zeros(len(coords))
    for j in range(len(coords)):
        (c_plus, p_plus), (c_minus, p_minus) = at(j, step), at(j, -step)
        gravity[j] = weight @ (c_plus - c_minus) / (2 * step)
        per_newton[j] = anterior @ (p_plus - p_minus) / (2 * step)
    at(0, 0.0)
    return OsimStatics(coordinates=tuple(names), muscles=[m.getName() for m in rows], moment_arms=arms, active=active,
                       passive=passive, max_isometric_force=f_max, gravity=gravity,
                       load_per_newton={"extension": per_newton, "flexion": -per_newton})


def _osim_constants(rows):
    """The Thelen constants of the .osim's muscles (they must all share them)."""
    from trunk_drake.muscle import thelen

    values = {(m.get_FmaxTendonStrain(), m.get_FmaxMuscleStrain(), m.get_KshapePassive(), m.get_KshapeActive(), m.get_Af(),
               m.get_Flen()) for m in rows}
    if len(values) != 1:
        raise ValueError(f"the .osim's Thelen muscles use {len(values)} different sets of constants; expected one")
    e0_t, e0_m, k_pe, gamma, af, flen = values.pop()
    return thelen.ThelenConstants(tendon_strain_at_fmax=e0_t, passive_strain_at_fmax=e0_m, k_passive=k_pe, gamma=gamma, af=af, flen=flen)
