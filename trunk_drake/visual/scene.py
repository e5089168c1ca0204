"""The passenger in a Drake Meshcat scene: bones per segment, muscle lines, the platform.

Scene paths: ``/<figure>/bones/<segment>`` (one node per rigid segment, its world pose is
what moves), ``/<figure>/muscles/<group>/<muscle>`` (one line per muscle, world coordinates)
and ``/platform``. A figure is one copy of the trunk (a second, translucent one can show
measured motion next to the model's).
"""

from __future__ import annotations

import numpy as np
from pydrake.geometry import Box, Mesh, MeshcatAnimation, Rgba
from pydrake.math import RigidTransform, RotationMatrix

from trunk_drake.visual.geometry import Drawing, Motion
from trunk_drake.visual.meshes import bone_meshes

BONE_RGBA = (0.92, 0.89, 0.81, 1.0)
MODEL_GHOST_RGBA = (0.92, 0.89, 0.81, 0.55)  # the model's bones when measured motion is shown with them
DATA_GHOST_RGBA = (0.25, 0.55, 0.95, 0.45)  # the bones posed by measured kinematics
PLATFORM_RGBA = (0.36, 0.38, 0.44, 1.0)
PLATFORM_SIZE = (0.50, 0.45, 0.04)  # m: anterior-posterior, lateral, thickness (illustrative seat)
MUSCLE_LINE_WIDTH = 2.0  # pixels where the browser supports wide lines
GROUP_RGB = {  # still pictures: one colour per muscle group
    "sacrospinalis": (0.80, 0.15, 0.15), "transversospinalis": (0.90, 0.50, 0.10),
    "quadratus_lumborum": (0.55, 0.30, 0.70), "internal_oblique": (0.10, 0.55, 0.30),
    "external_oblique": (0.15, 0.40, 0.80), "rectus_abdominis": (0.85, 0.20, 0.60),
    "psoas_major": (0.45, 0.25, 0.10),
}
OTHER_GROUP_RGB = (0.3, 0.3, 0.3)


class PassengerScene:
    """One figure of the trunk model in a Meshcat scene, at rest until posed or animated."""

    def __init__(self, meshcat, drawing: Drawing, figure: str = "passenger", muscles: bool = True,
                 rgba: tuple = BONE_RGBA):
        self.meshcat, self.drawing, self.figure = meshcat, drawing, figure
        model = drawing.model
        names = model.body_names
        bones = bone_meshes()
        rest = np.zeros(model.plant.num_positions())
        R, p = drawing.poses(rest)
        self.segment_paths = [f"/{figure}/bones/{s.name}" for s in drawing.segments]
        for seg, path in zip(drawing.segments, self.segment_paths):
            for b in seg.members:
                if names[b] in bones:
                    part = f"{path}/{names[b].replace(' ', '_')}"
                    meshcat.SetObject(part, Mesh(str(bones[names[b]])), Rgba(*rgba))
                    meshcat.SetTransform(part, _transform(R[seg.body].T @ R[b], R[seg.body].T @ (p[b] - p[seg.body])))
        self.muscle_paths = []
        if muscles:
            group_of = {m.name: m.group for m in model.spec.muscles}
            self.muscle_paths = [f"/{figure}/muscles/{group_of[m] or 'other'}/{m}" for m in model.muscles]
        self.pose(rest)

    def pose(self, q, muscle_rgb=None) -> None:
        """Show the figure at q (muscles coloured by group unless `muscle_rgb` (n_muscles, 3))."""
        R, p, _ = self.drawing.frame(q)
        for path, Rs, ps in zip(self.segment_paths, R, p):
            self.meshcat.SetTransform(path, _transform(Rs, ps))
        if not self.muscle_paths:
            return
        if muscle_rgb is None:
            group_of = {m.name: m.group for m in self.drawing.model.spec.muscles}
            muscle_rgb = [GROUP_RGB.get(group_of[m], OTHER_GROUP_RGB) for m in self.drawing.model.muscles]
        for path, points, rgb in zip(self.muscle_paths, self.drawing.polylines(q), muscle_rgb):
            self.meshcat.SetLine(path, points.T, MUSCLE_LINE_WIDTH, Rgba(*rgb, 1.0))

    def record(self, animation: MeshcatAnimation, motion: Motion) -> None:
        """Add the moving segments' poses, one per frame, to `animation`."""
        for s in motion.moving_segments:
            for f in range(len(motion.segment_p)):
                animation.SetTransform(f, self.segment_paths[s], _transform(motion.segment_R[f, s], motion.segment_p[f, s]))


class Platform:
    """The seat under the pelvis: its top touches the lowest point of the pelvis bones at rest,
    and it slides along the pelvis' anterior-posterior axis."""

    PATH = "/platform"

    def __init__(self, meshcat, drawing: Drawing):
        self.meshcat = meshcat
        model = drawing.model
        sacrum = model.body_names.index("sacrum")
        R, p = drawing.poses(np.zeros(model.plant.num_positions()))
        lowest = _lowest_bone_point(R[sacrum], p[sacrum])
        self.axis = R[sacrum][:, 0]  # pelvis_tx direction in the world
        self.rest = np.array([p[sacrum][0], p[sacrum][1], lowest - PLATFORM_SIZE[2] / 2])
        along = np.array([self.axis[0], self.axis[1], 0.0]) / np.linalg.norm(self.axis[:2])  # the seat stays level
        self.rotation = np.column_stack([along, np.cross([0.0, 0.0, 1.0], along), [0.0, 0.0, 1.0]])
        meshcat.SetObject(self.PATH, Box(*PLATFORM_SIZE), Rgba(*PLATFORM_RGBA))
        self.place(0.0)

    def transform(self, displacement: float) -> RigidTransform:
        return _transform(self.rotation, self.rest + displacement * self.axis)

    def place(self, displacement: float) -> None:
        self.meshcat.SetTransform(self.PATH, self.transform(displacement))

    def record(self, animation: MeshcatAnimation, displacement: np.ndarray) -> None:
        for f, x in enumerate(displacement):
            animation.SetTransform(f, self.PATH, self.transform(float(x)))


def _lowest_bone_point(R_sacrum, p_sacrum) -> float:
    """World height of the lowest vertex of the sacrum's bones (sacrum and hip bones)."""
    path = bone_meshes()["sacrum"]
    vertices = np.array([line.split()[1:4] for line in path.read_text().splitlines() if line.startswith("v ")], dtype=float)
    return float((vertices @ R_sacrum.T + p_sacrum)[:, 2].min())


def _transform(R, p) -> RigidTransform:
    return RigidTransform(RotationMatrix(np.asarray(R, dtype=float)), np.asarray(p, dtype=float))
