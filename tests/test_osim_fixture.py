"""A small hand-written .osim (tests/data/fixture_trunk.osim) against OpenSim 4.6, and bad input.

The fixture holds one of each element trunk-drake reads: WeldJoint, PinJoint and CustomJoints
with linear, SimmSpline, constant and MultiplierFunction transform axes (a spline translation of
a rotation's coordinate), a locked coordinate, coordinate couplers (piecewise linear with a
scale factor, linear), a Thelen2003Muscle and a Millard2012EquilibriumMuscle, fixed,
conditional and moving path points, and the wrap objects WrapSphere (quadrant -x),
WrapCylinder (all and -y) and WrapEllipsoid (z, and all with the midpoint method), a path
wrap with a point range and a path with two wraps.
"""

import warnings
from pathlib import Path

import numpy as np
import pytest

import trunk_drake as td
from trunk_drake.model.osim import OsimError, read_osim

FIXTURE = Path(__file__).parent / "data" / "fixture_trunk.osim"
N_POSES = 300


def _load(dofs="all"):
    with warnings.catch_warnings():  # the reader's warnings are checked in test_fixture_reader_reads_each_element
        warnings.simplefilter("ignore")
        return td.load_model(FIXTURE, dofs=dofs)


@pytest.mark.parametrize("couplers", [False, True], ids=["couplers_removed", "couplers_enforced"])
def test_fixture_matches_opensim(couplers):
    pytest.importorskip("opensim", reason="OpenSim 4.6 (pip opensim) is needed for this oracle test")
    from osim_oracle import OsimOracle

    model = _load()
    oracle = OsimOracle(FIXTURE, couplers)
    assert oracle.muscle_names == model.muscles
    rng = np.random.default_rng(7 + couplers)
    worst = np.zeros(4)
    wrapped = {m: 0 for m in model.muscles}
    conditional_off = 0
    for k in range(N_POSES):
        values = oracle.sample(rng)
        oracle.set(values)
        q = model.q_from_source(values)
        lengths = model.muscle_lengths(q)
        worst[0] = max(worst[0], np.abs(lengths - oracle.lengths()).max())
        arms = model.source_moment_arms(q)
        if k % 15 == 0:  # OpenSim's own computeMomentArm, coordinate by coordinate
            for name in arms:
                if name not in oracle.dependent:
                    coupled = sum(arms.get(n, 0.0) * w for n, w in zip(oracle.names, oracle.coupling(values, name)))
                    worst[1] = max(worst[1], np.abs(coupled - oracle.compute_moment_arm(name)).max())
        context = model.plant.CreateDefaultContext()
        model.plant.SetPositions(context, q)
        mass, com = oracle.mass_and_com()
        worst[2] = max(worst[2], abs(model.plant.CalcTotalMass(context) - mass), np.abs(model.center_of_mass(q) - com).max())
        # the plant itself holds the spline translation (a follower) at its q = 0 value
        worst[3] = max(worst[3], np.abs(model.plant.CalcCenterOfMassPositionInWorld(context) - com).max())
        for i, m in enumerate(model.muscles):
            path = oracle.muscles.get(i).getGeometryPath()
            wrapped[m] += path.getWrapSet().getSize() > 0 and path.getCurrentPath(oracle.state).getSize() > len(
                [j for j in range(path.getPathPointSet().getSize()) if path.getPathPointSet().get(j).isActive(oracle.state)])
        conditional_off += values["flex"] > -0.1
    print(f"\nfixture, couplers {'enforced' if couplers else 'removed'}: max |dL| {worst[0]:.1e} m, max |d moment arm| "
          f"{worst[1]:.1e} m, mass/com {worst[2]:.1e} (plant with the follower held: {worst[3]:.1e} m); "
          f"poses wrapped per muscle {wrapped}")
    assert worst[0] < 1e-5 and worst[1] < 1e-4 and worst[2] < 1e-9
    assert worst[3] < 1.2 * 0.012 * 21.0 / 27.2  # the spline: 1.2 x 1.2 cm under 21 of the model's 27.2 kg
    assert all(n >= 0.1 * N_POSES for m, n in wrapped.items() if m != "back_cyl") and wrapped["back_cyl"] > 0
    assert 0 < conditional_off < N_POSES


def test_fixture_reader_reads_each_element():
    with pytest.warns(UserWarning, match="Millard2012EquilibriumMuscle"):
        spec = read_osim(FIXTURE)
    assert {w.kind for w in spec.wraps} == {"sphere", "cylinder", "ellipsoid"}
    assert {w.quadrant for w in spec.wraps} == {"-x", "all", "-y", "z"}
    assert {j.function.kind for j in spec.joints} >= {"linear", "spline", "constant", "multiplier"}
    assert spec.coordinate("roll_tx").locked and spec.coordinate("flex").default == 0.05
    assert [c.name for c in spec.couplers] == ["roll_follows_flex", "upper_follows_flex"]
    assert any(s.condition for s in spec.sites) and any(s.motion for s in spec.sites)
    assert [m.source_type for m in spec.muscles] == ["Thelen2003Muscle", "Millard2012EquilibriumMuscle",
                                                     "Thelen2003Muscle", "Thelen2003Muscle"]
    assert spec.muscles[0].path_wraps[0].start == 1 and len(spec.muscles[3].path_wraps) == 2


def test_followers_move_with_their_coupler():
    """With flex free and roll coupled to it, the roller body follows: moment arms include it."""
    model = _load()
    q = model.q_from_source({"flex": -0.5, "roll": 1.5 * -0.25})
    assert model.source_coordinates(q)["roll"] == pytest.approx(-0.375)


def test_missing_file_invalid_xml_and_missing_lumbar_coordinates(tmp_path):
    with pytest.raises(OsimError, match="not found"):
        td.load_model(tmp_path / "nope.osim")
    bad = tmp_path / "bad.osim"
    bad.write_text("<OpenSimDocument><Model name='x'>")
    with pytest.raises(OsimError, match="not valid XML"):
        td.load_model(bad)
    with pytest.raises(ValueError, match="names no lumbar level bodies"):
        _load("sagittal")


def test_unsupported_elements_warn_once_each(tmp_path):
    """Elements the reader does not model are named, with what was done instead; none dropped silently."""
    text = FIXTURE.read_text()
    text = text.replace('<WrapSphere name="hip_ball">', '<WrapTorus name="ring"><inner_radius>0.01</inner_radius>'
                        '<outer_radius>0.05</outer_radius></WrapTorus><WrapSphere name="hip_ball">')
    text = text.replace('<PinJoint name="neck">', '<BallJoint name="shoulder"><socket_parent_frame>/bodyset/thorax'
                        '</socket_parent_frame><socket_child_frame>/bodyset/arm</socket_child_frame></BallJoint>'
                        '<PinJoint name="neck">')
    text = text.replace('<Body name="head">', '<Body name="arm"><mass>3</mass><mass_center>0 -0.2 0</mass_center>'
                        '<inertia>0.02 0.002 0.02 0 0 0</inertia></Body><Body name="head">')
    text = text.replace('<ForceSet name="forceset">\n      <objects>', '<ForceSet name="forceset">\n      <objects>'
                        '<CoordinateActuator name="motor"><coordinate>flex</coordinate></CoordinateActuator>')
    text = text.replace('<ConstraintSet name="constraintset">\n      <objects>', '<ConstraintSet name="constraintset">\n'
                        '      <objects><WeldConstraint name="glue"/>')
    path = tmp_path / "unsupported.osim"
    path.write_text(text)
    with pytest.warns(UserWarning) as record:
        read_osim(path)
    messages = [str(w.message) for w in record]
    for element, instead in [("WrapTorus", "paths do not wrap over it"), ("BallJoint", "welded with its joint frames aligned"),
                             ("CoordinateActuator", "ignored"), ("WeldConstraint", "ignored"),
                             ("Millard2012EquilibriumMuscle", "Thelen 2003 curves")]:
        hits = [m for m in messages if element in m]
        assert len(hits) == 1 and instead in hits[0], (element, messages)
    assert all("\n" not in m for m in messages)
