"""The compiled body kinematics (muscle paths, pelvis inertial force) against Drake's own."""

import numpy as np
import pytest
from pydrake.multibody.tree import BodyIndex, JacobianWrtVariable

import trunk_drake as td


@pytest.fixture(scope="module", params=[("sagittal", True), ("sagittal", False), ("spine3d", False)],
            ids=["sagittal", "sagittal-welded-pelvis", "spine3d"])
def model(request):
    dofs, pelvis_free = request.param
    return td.load_model(dofs, pelvis_free=pelvis_free)


def random_poses(model, n=20, seed=0):
    return np.random.default_rng(seed).uniform(-0.3, 0.3, (n, model.plant.num_positions()))


def test_body_poses_match_the_plant(model):
    plant = model.plant
    context = plant.CreateDefaultContext()
    for q in random_poses(model):
        plant.SetPositions(context, q)
        R, p = model._kinematics.poses(q)
        for b in range(plant.num_bodies()):
            X = plant.EvalBodyPoseInWorld(context, plant.get_body(BodyIndex(b))).GetAsMatrix34()
            np.testing.assert_allclose(R[b], X[:, :3], atol=1e-14)
            np.testing.assert_allclose(p[b], X[:, 3], atol=1e-14)


def test_mass_weighted_com_jacobian_matches_the_plant(model):
    plant = model.plant
    context = plant.CreateDefaultContext()
    mass = plant.CalcTotalMass(context)
    direction = np.array([0.6, -0.3, 0.74])
    for q in random_poses(model, seed=1):
        plant.SetPositions(context, q)
        J = plant.CalcJacobianCenterOfMassTranslationalVelocity(context, JacobianWrtVariable.kV, plant.world_frame(),
                                                                plant.world_frame())
        np.testing.assert_allclose(model.mass_weighted_com_jacobian(q, direction), mass * J.T @ direction, atol=1e-12)
