"""MyoTorso's bone meshes as Wavefront OBJ files in each body's frame, converted once and cached.

The STL files ship with `myo-sim` (`myo_sim/models/meshes/`); MuJoCo reads them when it
compiles MyoTorso and places each mesh geom in its body. The conversion writes, per body, one
OBJ (vertices in the body frame, smooth vertex normals) that Drake's Meshcat loads. The hip
bones (`r_pelvis.stl`, `l_pelvis.stl`) are not in MyoTorso: they are placed on our sacrum as
myo-sim's MyoFullBody places them (the MyoLeg pelvis and MyoTorso's sacrum both hang from the
`Full Body` root frame there). Nothing is downloaded; the cache folder is
``$TRUNK_DRAKE_CACHE`` or ``$XDG_CACHE_HOME/trunk-drake`` (default ``~/.cache/trunk-drake``).
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from importlib.metadata import version
from pathlib import Path

import numpy as np

from trunk_drake.model.paths import quat_matrix

FORMAT = 1  # bump when the conversion changes
BONE_GROUP = 0  # MyoTorso's visual bone geoms
HIP_BONES = ("pelvis_r", "pelvis_l")  # MyoLeg geoms on its `pelvis` body


def cache_dir() -> Path:
    """The user cache folder of trunk-drake."""
    if os.environ.get("TRUNK_DRAKE_CACHE"):
        return Path(os.environ["TRUNK_DRAKE_CACHE"])
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "trunk-drake"


def bone_meshes() -> dict[str, Path]:
    """OBJ file of the bones of each body (body name -> path), converted on first use."""
    folder = cache_dir() / f"meshes-myo-sim-{version('myo-sim')}-mujoco-{version('mujoco')}-v{FORMAT}"
    manifest = folder / "meshes.json"
    if not manifest.exists():
        _convert(folder)
    return {body: folder / name for body, name in json.loads(manifest.read_text()).items()}


def _convert(folder: Path) -> None:
    """Write the OBJ files and their manifest into a temporary folder, then move it in place
    (so concurrent first uses never see half a cache)."""
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=folder.name + ".", dir=folder.parent))
    try:
        manifest = {}
        for body, (vertices, faces) in _body_meshes().items():
            name = f"{body.replace(' ', '_')}.obj"
            (tmp / name).write_text(_obj_text(vertices, faces))
            manifest[body] = name
        (tmp / "meshes.json").write_text(json.dumps(manifest, indent=1))
        try:
            tmp.rename(folder)
        except OSError:  # another process finished first
            if not (folder / "meshes.json").exists():
                raise
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _body_meshes() -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Per body: vertices (n, 3) in the body frame and triangles (m, 3), all its bone geoms merged."""
    import mujoco

    from trunk_drake.model.myotorso import compile_myotorso

    torso = compile_myotorso()
    parts: dict[str, list] = {}
    for g in range(torso.ngeom):
        if torso.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH and torso.geom_bodyid[g] > 0 and torso.geom_group[g] == BONE_GROUP:
            body = mujoco.mj_id2name(torso, mujoco.mjtObj.mjOBJ_BODY, torso.geom_bodyid[g])
            parts.setdefault(body, []).append(_geom_mesh(torso, g, np.eye(3), np.zeros(3)))
    legs = _legs_model()
    R_sacrum_pelvis, p_sacrum_pelvis = _pelvis_in_sacrum(torso, legs)
    for name in HIP_BONES:
        g = mujoco.mj_name2id(legs, mujoco.mjtObj.mjOBJ_GEOM, name)
        parts.setdefault("sacrum", []).append(_geom_mesh(legs, g, R_sacrum_pelvis, p_sacrum_pelvis))
    out = {}
    for body, meshes in parts.items():
        offsets = np.cumsum([0] + [len(v) for v, _ in meshes])[:-1]
        out[body] = (np.vstack([v for v, _ in meshes]), np.vstack([f + o for (_, f), o in zip(meshes, offsets)]))
    return out


def _geom_mesh(m, g, R_out, p_out):
    """Vertices of mesh geom g in its body frame, mapped by (R_out, p_out), and its triangles."""
    mesh = int(m.geom_dataid[g])
    v0, nv = int(m.mesh_vertadr[mesh]), int(m.mesh_vertnum[mesh])
    f0, nf = int(m.mesh_faceadr[mesh]), int(m.mesh_facenum[mesh])
    in_body = m.mesh_vert[v0:v0 + nv] @ quat_matrix(m.geom_quat[g]).T + m.geom_pos[g]
    return in_body @ R_out.T + p_out, m.mesh_face[f0:f0 + nf].astype(np.int64)


def _legs_model():
    """myo-sim's MyoLeg fragment as MyoFullBody attaches it to the `Full Body` frame."""
    from myo_sim.build.compose import build_legs_spec

    return build_legs_spec().compile()


def _pelvis_in_sacrum(torso, legs):
    """Pose of MyoLeg's `pelvis` body in MyoTorso's `sacrum` frame, both under `Full Body`."""
    import mujoco

    pelvis = mujoco.mj_name2id(legs, mujoco.mjtObj.mjOBJ_BODY, "pelvis")
    root = mujoco.mj_name2id(legs, mujoco.mjtObj.mjOBJ_BODY, "myolegs_root")
    if legs.body_parentid[pelvis] != root:
        raise ValueError("myo-sim's MyoLeg pelvis is no longer a child of its root; update trunk_drake.visual.meshes")
    sacrum = mujoco.mj_name2id(torso, mujoco.mjtObj.mjOBJ_BODY, "sacrum")
    if mujoco.mj_id2name(torso, mujoco.mjtObj.mjOBJ_BODY, torso.body_parentid[sacrum]) != "Full Body":
        raise ValueError("MyoTorso's sacrum is no longer a child of `Full Body`; update trunk_drake.visual.meshes")
    R_fs, p_fs = quat_matrix(torso.body_quat[sacrum]), torso.body_pos[sacrum]
    R_fp, p_fp = quat_matrix(legs.body_quat[pelvis]), legs.body_pos[pelvis]
    return R_fs.T @ R_fp, R_fs.T @ (p_fp - p_fs)


def _obj_text(vertices: np.ndarray, faces: np.ndarray) -> str:
    """Wavefront OBJ with area-weighted vertex normals (smooth shading)."""
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    face_normals = np.cross(b - a, c - a)
    normals = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(normals, faces[:, k], face_normals)
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    lines = ["# trunk-drake: MyoTorso bones (myo-sim), metres, body frame"]
    lines += [f"v {x:.5f} {y:.5f} {z:.5f}" for x, y, z in vertices]
    lines += [f"vn {x:.4f} {y:.4f} {z:.4f}" for x, y, z in normals]
    lines += [f"f {i}//{i} {j}//{j} {k}//{k}" for i, j, k in faces + 1]
    return "\n".join(lines) + "\n"
