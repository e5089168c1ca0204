"""Read MyoTorso (myo-sim) into a ModelSpec.

MyoTorso is compiled once with MuJoCo (myo-sim ships it as an MJCF spec) and its numbers are
copied into plain dataclasses; MuJoCo is not used afterwards. Muscle Hill parameters are not
taken from MyoTorso (its MuJoCo muscle parameters are tuned to MuJoCo's own curve): they are
derived in `trunk_drake.model.architecture`.

MyoTorso's lumbar rhythm (its equality constraints on ``flex_extension``) becomes the spec's
`RhythmSpec`, with one correction: MuJoCo has no joint gearing, so MyoTorso makes its driver
``flex_extension`` the L5/S1 hinge itself, while in Lumbar_C_210 L5/S1 turns 0.125 of it
(models/reference_values.toml, kinematics.lumbar_rhythm). The reader restores that slope.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from trunk_drake.data import load_toml
from trunk_drake.model.levels import LEVELS
from trunk_drake.model.paths import quat_matrix
from trunk_drake.model.plant import opensim_coordinate
from trunk_drake.model.spec import (
    BodySpec,
    CouplingSpec,
    JointSpec,
    ModelSpec,
    MuscleSpec,
    PathElement,
    RhythmSpec,
    SiteSpec,
    WrapSpec,
)

_JOINT_KINDS = {2: "slide", 3: "hinge"}  # mjJNT_SLIDE, mjJNT_HINGE
_WRAP_KINDS = {2: "sphere", 5: "cylinder"}  # mjGEOM_SPHERE, mjGEOM_CYLINDER
_WRAP_SITE, _WRAP_SPHERE, _WRAP_CYLINDER = 3, 4, 5  # mjtWrap
_EQ_JOINT = 2  # mjEQ_JOINT
RHYTHM_DRIVER = "flex_extension"  # Lumbar_C_210's net lumbar flexion-extension coordinate
RHYTHM_LEVELS = tuple(opensim_coordinate(f"{level}_FE")[0] for level in LEVELS)  # flexion joints, L5/S1 ... L1/L2


def lumbar_c210_l5_s1_slope() -> float:
    """Lumbar_C_210's L5/S1 flexion per unit of flex_extension (models/reference_values.toml)."""
    return float(load_toml("reference_values.toml")["kinematics"]["lumbar_rhythm"]["l5_s1_flexion_slope"]["value"])


def myotorso_rhythm(couplings, l5_s1_slope: float) -> RhythmSpec:
    """The flexion rhythm of MyoTorso's equality constraints, L5/S1 turning `l5_s1_slope` of the driver.

    ``l5_s1_slope=1`` is MyoTorso as shipped (its driver is the L5/S1 hinge);
    `lumbar_c210_l5_s1_slope()` is the original model's rhythm.
    """
    ratios, routing = {RHYTHM_DRIVER: float(l5_s1_slope)}, {}
    for c in couplings:
        if c.driver != RHYTHM_DRIVER:
            continue
        if c.coef[0] != 0.0 or any(c.coef[2:]):
            raise ValueError(f"MyoTorso coupling {c.name} is not proportional to {RHYTHM_DRIVER} (coefficients {c.coef})")
        (ratios if c.joint in RHYTHM_LEVELS else routing)[c.joint] = c.coef[1]
    missing = [j for j in RHYTHM_LEVELS if j not in ratios]
    if missing:
        raise ValueError(f"MyoTorso has no coupling of {missing} to {RHYTHM_DRIVER}: cannot build its lumbar rhythm")
    source = "MyoTorso equality constraints" + ("" if l5_s1_slope == 1.0 else f", L5/S1 slope {l5_s1_slope:g} of Lumbar_C_210")
    return RhythmSpec(RHYTHM_DRIVER, RHYTHM_LEVELS, tuple(ratios[j] for j in RHYTHM_LEVELS),
                      tuple(routing), tuple(routing.values()), source)


def compile_myotorso():
    """The compiled MuJoCo model of MyoTorso (used here and by the MuJoCo oracle tests)."""
    from myo_sim.build.compose import build_spec

    return build_spec("myotorso").compile()


def _name(m, objtype, i) -> str:
    import mujoco

    return mujoco.mj_id2name(m, objtype, i)


def _landmarks(m, body_names) -> tuple[SiteSpec, ...]:
    """Thoracic vertebral-body centres T1..T12 (centres of MyoTorso's vertebra meshes, which
    MuJoCo places at the mesh centroid) and the shoulder sites."""
    import re

    import mujoco

    out = []
    for g in range(m.ngeom):
        mesh = int(m.geom_dataid[g])
        if m.geom_type[g] != mujoco.mjtGeom.mjGEOM_MESH or mesh < 0:
            continue
        match = re.search(r"thoracic(\d+)", _name(m, mujoco.mjtObj.mjOBJ_MESH, mesh) or "")
        if match:
            out.append(SiteSpec(f"T{int(match.group(1))}", body_names[m.geom_bodyid[g]], m.geom_pos[g].copy()))
    for side in ("l", "r"):
        s = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, f"Shoulder_{side}")
        if s >= 0:
            out.append(SiteSpec(f"shoulder_{side}", body_names[m.site_bodyid[s]], m.site_pos[s].copy()))
    return tuple(sorted(out, key=lambda s: s.name))


@lru_cache(maxsize=1)
def read_myotorso() -> ModelSpec:
    """MyoTorso geometry, inertia, joints, path sites, wraps and muscles (without Hill lengths)."""
    import mujoco
    import myo_sim  # noqa: F401  (version for provenance)
    from importlib.metadata import version

    m = compile_myotorso()
    ot = mujoco.mjtObj
    body_names = [_name(m, ot.mjOBJ_BODY, i) for i in range(m.nbody)]

    bodies = []
    for i in range(1, m.nbody):
        r = quat_matrix(m.body_iquat[i])
        parent = int(m.body_parentid[i])
        bodies.append(
            BodySpec(
                name=body_names[i],
                parent=None if parent == 0 else body_names[parent],
                pos=m.body_pos[i].copy(),
                quat=m.body_quat[i].copy(),
                mass=float(m.body_mass[i]),
                com=m.body_ipos[i].copy(),
                inertia=r @ np.diag(m.body_inertia[i]) @ r.T,
            )
        )

    joints = []
    for j in range(m.njnt):
        kind = _JOINT_KINDS.get(int(m.jnt_type[j]))
        if kind is None:
            raise ValueError(f"MyoTorso joint {_name(m, ot.mjOBJ_JOINT, j)} has unsupported type {m.jnt_type[j]}")
        joints.append(
            JointSpec(
                name=_name(m, ot.mjOBJ_JOINT, j),
                body=body_names[m.jnt_bodyid[j]],
                kind=kind,
                axis=m.jnt_axis[j].copy(),
                anchor=m.jnt_pos[j].copy(),
                range=(float(m.jnt_range[j, 0]), float(m.jnt_range[j, 1])),
            )
        )

    sites = tuple(
        SiteSpec(_name(m, ot.mjOBJ_SITE, s), body_names[m.site_bodyid[s]], m.site_pos[s].copy())
        for s in range(m.nsite)
    )

    wrap_index: dict[int, int] = {}
    wraps: list[WrapSpec] = []
    muscles = []
    for a in range(m.nu):
        tendon = int(m.actuator_trnid[a, 0])
        path = []
        adr, num = int(m.tendon_adr[tendon]), int(m.tendon_num[tendon])
        for k in range(adr, adr + num):
            wtype, obj = int(m.wrap_type[k]), int(m.wrap_objid[k])
            if wtype == _WRAP_SITE:
                path.append(PathElement("site", obj))
            elif wtype in (_WRAP_SPHERE, _WRAP_CYLINDER):
                if obj not in wrap_index:
                    wrap_index[obj] = len(wraps)
                    wraps.append(
                        WrapSpec(
                            name=_name(m, ot.mjOBJ_GEOM, obj),
                            body=body_names[m.geom_bodyid[obj]],
                            kind=_WRAP_KINDS[int(m.geom_type[obj])],
                            radius=float(m.geom_size[obj, 0]),
                            pos=m.geom_pos[obj].copy(),
                            quat=m.geom_quat[obj].copy(),
                        )
                    )
                path.append(PathElement("wrap", wrap_index[obj], int(round(m.wrap_prm[k]))))
            else:
                raise ValueError(f"muscle {_name(m, ot.mjOBJ_ACTUATOR, a)}: unsupported wrap type {wtype}")
        muscles.append(
            MuscleSpec(
                name=_name(m, ot.mjOBJ_ACTUATOR, a),
                path=tuple(path),
                max_isometric_force=float(m.actuator_gainprm[a, 2]),
            )
        )

    couplings = []
    for e in range(m.neq):
        if int(m.eq_type[e]) != _EQ_JOINT:
            continue
        driver = int(m.eq_obj2id[e])
        couplings.append(
            CouplingSpec(
                name=_name(m, ot.mjOBJ_EQUALITY, e),
                joint=_name(m, ot.mjOBJ_JOINT, int(m.eq_obj1id[e])),
                driver=None if driver < 0 else _name(m, ot.mjOBJ_JOINT, driver),
                coef=tuple(float(c) for c in m.eq_data[e, :5]),
            )
        )

    return ModelSpec(
        name="myotorso",
        landmarks=_landmarks(m, body_names),
        bodies=tuple(bodies),
        joints=tuple(joints),
        sites=sites,
        wraps=tuple(wraps),
        muscles=tuple(muscles),
        couplings=tuple(couplings),
        rhythm=myotorso_rhythm(couplings, lumbar_c210_l5_s1_slope()),
        gravity=m.opt.gravity.copy(),
        source=f"myo-sim {version('myo-sim')} myotorso (MuJoCo {mujoco.__version__})",
    )
