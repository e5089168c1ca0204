"""The passenger's lumped segments (model/anthropometry.py) against independent constructions."""

from dataclasses import replace

import numpy as np
import pytest

from trunk_drake.data import load_toml
from trunk_drake.model.anthropometry import Passenger, lumped_segments, with_passenger, with_upper_body_mass
from trunk_drake.model.plant import build_plant
from trunk_drake.model.spec import BodySpec
from trunk_drake.model.trunk_model import load_model


@pytest.fixture(scope="module")
def spec():
    return load_model("sagittal").spec


def _as_welded_bodies(spec, passenger):
    """The same segments as separate bodies welded to the torso (no parallel-axis algebra)."""
    extra = tuple(BodySpec(s.name, "torso", np.zeros(3), np.array([1.0, 0, 0, 0]), s.mass, s.com, s.inertia)
                  for s in lumped_segments(spec, passenger))
    return replace(spec, bodies=spec.bodies + extra)


@pytest.mark.parametrize("passenger", [Passenger(), Passenger(body_mass=95.0, stature=1.9), Passenger(arms="none")])
def test_lumped_thorax_has_the_dynamics_of_separate_segments(spec, passenger):
    lumped, _ = build_plant(with_passenger(spec, passenger), "sagittal")
    separate, _ = build_plant(_as_welded_bodies(spec, passenger), "sagittal")
    rng = np.random.default_rng(3)
    cl, cs = lumped.CreateDefaultContext(), separate.CreateDefaultContext()
    for _ in range(5):
        q = rng.uniform(-0.3, 0.3, lumped.num_positions())
        lumped.SetPositions(cl, q)
        separate.SetPositions(cs, q)
        np.testing.assert_allclose(lumped.CalcMassMatrix(cl), separate.CalcMassMatrix(cs), rtol=1e-10, atol=1e-12)
        np.testing.assert_allclose(lumped.CalcGravityGeneralizedForces(cl), separate.CalcGravityGeneralizedForces(cs),
                                   rtol=1e-10, atol=1e-10)


def test_added_mass_follows_de_leva(spec):
    deleva = load_toml("reference_values.toml")["anthropometry"]["deleva1996"]
    mass = 80.0
    added = sum(s.mass for s in lumped_segments(spec, Passenger(body_mass=mass)))
    head_neck = sum(spec.body(b).mass for b in ("head", "neck"))
    arms = 2 * sum(deleva[f"male_{k}"]["value"][0] for k in ("upper_arm", "forearm", "hand"))
    assert added == pytest.approx(deleva["male_head"]["value"][0] * mass - head_neck + arms * mass, rel=1e-12)
    upper = with_passenger(spec, Passenger(body_mass=mass)).body("torso").mass
    assert upper == pytest.approx(spec.body("torso").mass + added)


def test_hanging_arms_start_at_the_shoulder_and_reach_below_it(spec):
    arms = {s.name: s for s in lumped_segments(spec, Passenger())}
    assert arms["upper_arm_r"].com[1] > arms["forearm_r"].com[1] > arms["hand_r"].com[1]
    assert arms["upper_arm_r"].com[2] == -arms["upper_arm_l"].com[2] > 0


def test_shoulder_joint_centre_is_myoarms_in_myotorso():
    """The recorded glenohumeral centre equals myo-sim's MyoArm attached to MyoTorso."""
    mujoco = pytest.importorskip("mujoco")
    from myo_sim.build.compose import build_spec

    m = build_spec("myotorso_arms").compile()
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    torso = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "torso")
    R, p = d.xmat[torso].reshape(3, 3), d.xpos[torso]
    recorded = load_toml("reference_values.toml")["anthropometry"]["myoarm_shoulder_joint_centre"]["value"]
    for side, sign in (("r", 1.0), ("l", -1.0)):
        joint = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, f"shoulder_elv_{side}")
        centre = R.T @ (d.xanchor[joint] - p)
        np.testing.assert_allclose(centre, np.array(recorded) * [1, 1, sign], atol=5e-4)


@pytest.mark.parametrize("kwargs,match", [({"body_mass": 5.0}, "body_mass"), ({"stature": 3.0}, "stature"),
                                          ({"arms": "folded"}, "arms")])
def test_bad_passenger_is_a_clear_error(kwargs, match):
    with pytest.raises(ValueError, match=match):
        Passenger(**kwargs)


def test_upper_body_mass_scales_the_thorax_only(spec):
    """Gravity forces and the mass matrix are linear in the thorax mass (its centre of mass and
    inertia ellipsoid kept): the changes for a 20 % error are twice those for 10 %."""
    thorax = next(b for b in spec.bodies if b.name == "torso")
    scaled = with_upper_body_mass(spec, 1.2)
    assert sum(b.mass for b in scaled.bodies) == pytest.approx(sum(b.mass for b in spec.bodies) + 0.2 * thorax.mass)
    plants = [build_plant(with_upper_body_mass(spec, s), "sagittal")[0] for s in (1.0, 1.1, 1.2)]
    q = np.random.default_rng(5).uniform(-0.2, 0.2, plants[0].num_positions())
    gravity, mass = [], []
    for plant in plants:
        context = plant.CreateDefaultContext()
        plant.SetPositions(context, q)
        gravity.append(plant.CalcGravityGeneralizedForces(context))
        mass.append(plant.CalcMassMatrix(context))
    assert np.abs(gravity[1] - gravity[0]).max() > 1e-3
    np.testing.assert_allclose(gravity[2] - gravity[0], 2 * (gravity[1] - gravity[0]), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(mass[2] - mass[0], 2 * (mass[1] - mass[0]), rtol=1e-9, atol=1e-12)
    with pytest.raises(ValueError, match="upper-body mass scale"):
        with_upper_body_mass(spec, 0.0)
