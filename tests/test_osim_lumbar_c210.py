"""Lumbar_C_210.osim read by trunk-drake (no OpenSim) against OpenSim 4.6 on the same file.

At 200 random poses within the coordinate ranges, with the file's coordinate couplers removed
(every coordinate free: ``dofs="all"``) and enforced (dependent coordinates from their
couplers, moment arms about the independent ones along the couplers): every musculotendon
length, every moment arm, total mass, centre of mass, and Thelen tendon forces at static
fiber equilibrium with random activations: OpenSim's forces at our equilibrium fiber lengths
within 1e-6 relative, and OpenSim's own equilibrium (where its solver converges) within its
solver tolerance.
"""

import numpy as np
import pytest

import trunk_drake as td

osim = pytest.importorskip("opensim", reason="OpenSim 4.6 (pip opensim) is needed for this oracle test")
from osim_oracle import OsimOracle, thelen_equilibrium  # noqa: E402

N_POSES = 200


@pytest.fixture(scope="module")
def ours(lumbar_c210_path):
    return td.load_model(lumbar_c210_path, dofs="all")


def _compare(model, oracle, values, enforced):
    """Errors (length, moment arm, mass, com) and the number of wrapped paths at one pose."""
    oracle.set(values)
    q = model.q_from_source(values)
    state = model.path_state(q)
    ref_lengths = oracle.lengths()
    ours_ma = model.source_moment_arms(q)
    gen = oracle.generalized_forces()
    names = oracle.names
    ma_err = 0.0
    if enforced:
        ours_full = np.column_stack([ours_ma.get(n, np.zeros(len(ref_lengths))) for n in names])
        for ind in {n for n in ours_ma if n not in oracle.dependent}:
            c = oracle.coupling(values, ind)
            ma_err = max(ma_err, np.abs(ours_full @ c - gen @ c).max())
    else:
        for name, arm in ours_ma.items():
            ma_err = max(ma_err, np.abs(arm - gen[:, names.index(name)]).max())
    context = model.plant.CreateDefaultContext()
    model.plant.SetPositions(context, q)
    mass, com = oracle.mass_and_com()
    mass_err = abs(model.plant.CalcTotalMass(context) - mass)
    com_err = np.abs(model.plant.CalcCenterOfMassPositionInWorld(context) - com).max()
    return np.abs(state.lengths - ref_lengths).max(), ma_err, mass_err, com_err, state.lengths


@pytest.mark.parametrize("couplers", [False, True], ids=["couplers_removed", "couplers_enforced"])
def test_geometry_mass_and_thelen_forces_match_opensim(ours, lumbar_c210_path, couplers):
    oracle = OsimOracle(lumbar_c210_path, couplers)
    assert oracle.muscle_names == ours.muscles
    rng = np.random.default_rng(210 + couplers)
    worst = np.zeros(6)
    wrapped = set()
    straight = {}
    for k in range(N_POSES):
        values = oracle.sample(rng)
        l_err, ma_err, mass_err, com_err, lengths = _compare(ours, oracle, values, couplers)
        worst[:4] = np.maximum(worst[:4], (l_err, ma_err, mass_err, com_err))
        if k % 10 == 0:  # Thelen forces (each needs OpenSim's equilibrium solve of all 210 muscles)
            activation = rng.uniform(0.01, 1.0, len(lengths))
            eq = thelen_equilibrium(ours, lengths, activation)
            f_max = ours.muscle_array("max_isometric_force")
            ref = oracle.tendon_forces(activation, eq.fiber_length)
            worst[4] = max(worst[4], np.max(np.abs(eq.tendon_force - ref) / np.maximum(np.abs(ref), 1e-9 * f_max)))
            ref_eq = oracle.equilibrium_tendon_forces(activation)
            ok = np.isfinite(ref_eq)
            assert ok.sum() >= 150, f"OpenSim's equilibrium failed for {np.sum(~ok)} muscles"
            # OpenSim stops at |force error| < 1e-8 F_max: smaller forces relative to 1e-3 F_max
            worst[5] = max(worst[5], np.max(np.abs(eq.tendon_force - ref_eq)[ok] / np.maximum(np.abs(ref_eq), 1e-3 * f_max)[ok]))
        # paths whose length differs from the polyline through their points: they wrap here
        for i, m in enumerate(ours.spec.muscles):
            if m.path_wraps:
                pts = np.array([oracle.muscles.get(i).getGeometryPath().getPathPointSet().get(j).getLocationInGround(oracle.state).to_numpy()
                                for j in range(len(m.path))])
                straight[m.name] = np.linalg.norm(np.diff(pts, axis=0), axis=1).sum()
                if abs(lengths[i] - straight[m.name]) > 1e-6:
                    wrapped.add(m.name)
    print(f"\ncouplers {'enforced' if couplers else 'removed'}, {N_POSES} poses: max |dL| {worst[0]:.2e} m, "
          f"max |d moment arm| {worst[1]:.2e} m, |d mass| {worst[2]:.1e} kg, |d com| {worst[3]:.1e} m, "
          f"Thelen force rel. {worst[4]:.1e} (at OpenSim's equilibrium {worst[5]:.1e}); {len(wrapped)} of 26 wrapping paths wrapped at some pose")
    assert worst[0] < 1e-5 and worst[1] < 1e-4
    assert worst[2] < 1e-9 and worst[3] < 1e-9
    assert worst[4] < 1e-6 and worst[5] < 1e-5
    assert len(wrapped) >= 20, f"too few paths wrapped to exercise the wrap surfaces: {sorted(wrapped)}"


def test_fast_moment_arms_equal_compute_moment_arm(lumbar_c210_path):
    """The oracle's all-coordinates moment arms equal OpenSim's computeMomentArm (with couplers)."""
    oracle = OsimOracle(lumbar_c210_path, couplers=True)
    rng = np.random.default_rng(3)
    for _ in range(2):
        values = oracle.sample(rng)
        oracle.set(values)
        gen = oracle.generalized_forces()
        for ind in ("flex_extension", "lat_bending", "axial_rotation"):
            np.testing.assert_allclose(gen @ oracle.coupling(values, ind), oracle.compute_moment_arm(ind), atol=1e-12)


def test_opensim4_document_of_the_same_model(lumbar_c210_path, tmp_path):
    """The 4.x document OpenSim writes for this model reads to the same geometry."""
    oracle = OsimOracle(lumbar_c210_path, couplers=False)
    oracle.model.printToXML(str(tmp_path / "lumbar4.osim"))
    from trunk_drake.model.osim import read_osim

    assert "OpenSim document version 4" in read_osim(tmp_path / "lumbar4.osim").source
    ours4 = td.load_model(tmp_path / "lumbar4.osim", dofs="all")
    oracle4 = OsimOracle(tmp_path / "lumbar4.osim", couplers=False)
    rng = np.random.default_rng(4)
    for _ in range(20):
        values = oracle4.sample(rng)
        oracle4.set(values)
        np.testing.assert_allclose(ours4.muscle_lengths(ours4.q_from_source(values)), oracle4.lengths(), atol=1e-9)


def test_configurations_on_the_file(lumbar_c210_path):
    """sagittal / spine3d map onto the file's lumbar coordinates with trunk-drake's signs."""
    sag = td.load_model(lumbar_c210_path, dofs="sagittal")
    assert sag.coordinates == ["pelvis_tx", "L5_S1_FE", "L4_L5_FE", "L3_L4_FE", "L2_L3_FE", "L1_L2_FE"]
    q = np.array([0.0, 0.05, 0.0, 0.0, 0.0, 0.0])  # 0.05 rad of L5/S1 flexion
    values = sag.source_coordinates(q)
    assert values["flex_extension"] == pytest.approx(-0.05 / 0.125)  # the file's L5/S1 axis is 0.125 flex_extension about +z
    assert values["LB_wrapjnt_r3"] == pytest.approx(0.6 * values["flex_extension"])  # kept coupler (routing body)
    assert values["L4_L5_FE"] == 0.0  # level couplers removed: the levels are independent
    flexed = sag.muscle_lengths(q)
    neutral = sag.muscle_lengths(np.zeros(6))
    back = [i for i, m in enumerate(sag.muscles) if m.startswith(("IL_", "LTpL_"))]
    assert np.all(flexed[back] >= neutral[back] - 1e-12)  # flexion lengthens the back extensors
    assert set(sag.groups) == {"sacrospinalis", "transversospinalis", "quadratus_lumborum", "internal_oblique",
                               "external_oblique", "rectus_abdominis", "psoas_major"}
    spine = td.load_model(lumbar_c210_path, dofs="spine3d")
    assert len(spine.coordinates) == 15 and spine.spec.landmark("T6").body == "torso"


def test_torso_frame_is_myotorsos(lumbar_c210_path):
    """The landmarks borrowed from MyoTorso sit in the same torso frame (mass, COM, joint offset)."""
    ours = td.load_model(lumbar_c210_path).spec
    myo = td.load_model().spec
    a, b = ours.body("torso"), myo.body("torso")
    assert a.mass == pytest.approx(b.mass) and np.allclose(a.com, b.com) and np.allclose(a.pos, b.pos)
