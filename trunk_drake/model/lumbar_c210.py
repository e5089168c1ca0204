"""Compare the model with the original OpenSim Lumbar_C_210 model (an oracle; needs `opensim`).

MyoTorso was converted from Christophy et al.'s Lumbar_C_210.osim. This module loads that
file with OpenSim, reads its musculotendon lengths at the neutral posture and its Thelen
parameters, and compares them with ours. The .osim file itself is never copied.
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



@dataclass
class OsimRhythmStatics:
    """Lumbar_C_210 in OpenSim with its couplers enforced, at one posture, in trunk-drake's terms.

    Everything is about ``lumbar_FE = -flex_extension`` (flexion positive; Lumbar_C_210's level
    slopes sum to 1, so it is also the sum of the level angles). `moment_arms` are OpenSim's own
    (``Muscle.computeMomentArm`` about flex_extension, sign flipped); `active`/`passive` are the
    rigid-tendon fiber forces along the tendon at full activation and zero velocity from OpenSim's
    Thelen2003Muscle curves with the .osim's parameters (as its Static Optimization Tool uses them);
    `gravity` is the generalized gravity force and `load_per_newton` the generalized force of a unit
    load at `points` (torso frame, equal shares) along `direction` (M g . dc/dq for the centre of mass
    c and dp/dq . direction, by central differences along the coupled motion, with OpenSim
    assembling the couplers; OpenSim's potential energy would include the muscles' elastic energy).
    """

    muscles: list[str]
    moment_arms: np.ndarray
    active: np.ndarray
    passive: np.ndarray
    max_isometric_force: np.ndarray
    gravity: float
    load_per_newton: dict[str, float]


def osim_rhythm_statics(osim_path: str, points, flexion: float = 0.0, step: float = 1e-5) -> OsimRhythmStatics:
    """`OsimRhythmStatics` of the .osim at ``lumbar_FE = flexion`` with horizontal loads at `points`.

    The loads push along the pelvis' anterior direction (``"extension"``: the subject pushes back
    against it) and posterior direction (``"flexion"``), as trunk_drake.optim.strength.
    """
    import opensim

    from trunk_drake.muscle import thelen

    opensim.Logger.setLevelString("error")
    model = opensim.Model(str(osim_path))
    muscles = model.getMuscles()
    state = model.initSystem()
    driver = model.getCoordinateSet().get("flex_extension")
    torso = model.getBodySet().get("torso")
    sacrum = model.getBodySet().get("sacrum")

    def pose(theta):
        driver.setValue(state, -theta, True)  # enforce the couplers (OpenSim assembles the dependent coordinates)
        model.realizePosition(state)

    def vec(v):
        return np.array([v.get(k) for k in range(3)])

    def load_points():
        return np.array([vec(torso.findStationLocationInGround(state, opensim.Vec3(*p))) for p in points])

    pose(flexion)
    model.realizeVelocity(state)
    gravity = vec(model.getGravity())
    weight = model.getTotalMass(state) * gravity
    up = -gravity / np.linalg.norm(gravity)
    R = sacrum.getTransformInGround(state).R()
    anterior = np.array([R.get(k, 0) for k in range(3)])
    anterior -= (anterior @ up) * up
    anterior /= np.linalg.norm(anterior)
    rows = [opensim.Thelen2003Muscle.safeDownCast(muscles.get(i)) for i in range(muscles.getSize())]
    arms = np.array([-m.computeMomentArm(state, driver) for m in rows])
    f_max = np.array([m.getMaxIsometricForce() for m in rows])
    active = np.array([m.calcInextensibleTendonActiveFiberForce(state, 1.0) for m in rows])
    params = thelen.MuscleParameters(f_max, [m.getOptimalFiberLength() for m in rows], [m.getTendonSlackLength() for m in rows],
                                     [m.getPennationAngleAtOptimalFiberLength() for m in rows])
    lengths = np.array([m.getLength(state) for m in rows])
    passive = thelen.rigid_tendon_force_split(lengths, np.zeros(len(rows)), params, _osim_constants(rows)).passive

    pose(flexion + step)
    c_plus, p_plus = vec(model.calcMassCenterPosition(state)), load_points()
    pose(flexion - step)
    c_minus, p_minus = vec(model.calcMassCenterPosition(state)), load_points()
    pose(flexion)
    dp = (p_plus - p_minus).mean(axis=0) / (2 * step)  # equal shares
    return OsimRhythmStatics(
        muscles=[m.getName() for m in rows], moment_arms=arms, active=active, passive=passive, max_isometric_force=f_max,
        gravity=float(weight @ (c_plus - c_minus) / (2 * step)),
        load_per_newton={"extension": float(dp @ anterior), "flexion": float(-dp @ anterior)},
    )


def _osim_constants(rows):
    """The Thelen constants of the .osim's muscles (they must all share them)."""
    from trunk_drake.muscle import thelen

    values = {(m.get_FmaxTendonStrain(), m.get_FmaxMuscleStrain(), m.get_KshapePassive(), m.get_KshapeActive(), m.get_Af(),
               m.get_Flen()) for m in rows}
    if len(values) != 1:
        raise ValueError(f"the .osim's Thelen muscles use {len(values)} different sets of constants; expected one")
    e0_t, e0_m, k_pe, gamma, af, flen = values.pop()
    return thelen.ThelenConstants(tendon_strain_at_fmax=e0_t, passive_strain_at_fmax=e0_m, k_passive=k_pe, gamma=gamma, af=af, flen=flen)
