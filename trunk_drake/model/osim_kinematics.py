"""Muscle path kinematics of an OpenSim model on the Drake plant (see osim_config for followers).

Per evaluation: the model's coordinates c(q); bodies with follower axes re-posed from the
plant's body poses (their subtree moved with them); conditional path points switched on or off;
moving path points placed; then the OpenSim path kernel, and moment arms
``-dL/dq = -(dL/d(plant axes) + dL/d(follower axes) dv/dq + moving-point terms)``.
"""

from __future__ import annotations

import numpy as np

from trunk_drake.model.osim_config import AxisChoice, SourceCoordinates
from trunk_drake.model.osim_paths import OsimPaths
from trunk_drake.model.paths import PathState, quat_matrix
from trunk_drake.model.spec import ModelSpec

_CONDITION_TOLERANCE = 1e-5  # OpenSim's ConditionalPathPoint range margin


def _rotation(axis, angle) -> np.ndarray:
    a = np.asarray(axis, dtype=float) / np.linalg.norm(axis)
    K = np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * (K @ K)


class OsimKinematics:
    """Lengths, moment arms and velocities of an OpenSim spec's muscles on a built plant."""

    def __init__(self, spec: ModelSpec, coords, body_names: list[str], coord_moves: np.ndarray):
        self.spec = spec
        self.nq = len(coords)
        self._body_index = {n: i for i, n in enumerate(body_names)}
        choices = [None if c.source_joint is None else AxisChoice(c.name, spec.joint(c.source_joint), c.sign) for c in coords]
        self.source = SourceCoordinates(spec, choices)
        plant_joints = {c.source_joint: k for k, c in enumerate(coords) if c.source_joint is not None}
        self._plant_joints = plant_joints
        self._coords = coords
        self._fixed = self.source.fixed_values(set(plant_joints))
        self.followers = self.source.followers(set(plant_joints))
        follower_bodies = {j.body for j in self.followers}
        self._follower_bodies = sorted(follower_bodies, key=self._depth)
        self._body_joints = {b: [j for j in spec.joints if j.body == b] for b in self._follower_bodies}
        self._subtree = {b: self._descendants(b) for b in self._follower_bodies}
        moves = np.zeros((len(body_names), len(self.followers)))
        for k, j in enumerate(self.followers):
            for name in self._subtree[j.body]:
                moves[self._body_index[name], k] = 1.0
        kinds = [c.kind for c in coords] + [j.kind for j in self.followers]
        self.paths = OsimPaths(spec, body_names, kinds, np.hstack([coord_moves, moves]), self.nq)
        self._follower_index = {j.name: k for k, j in enumerate(self.followers)}
        self._moving = [i for i, s in enumerate(spec.sites) if s.motion is not None]
        self._conditional = [i for i, s in enumerate(spec.sites) if s.condition is not None]
        self._site_body = np.array([self._body_index[s.body] for s in spec.sites], dtype=int)

    def _depth(self, name: str) -> int:
        parent = self.spec.body(name).parent
        return 0 if parent is None else 1 + self._depth(parent)

    def _descendants(self, root: str) -> list[str]:
        out, todo = [], [root]
        while todo:
            name = todo.pop()
            out.append(name)
            todo.extend(self.spec.children(name))
        return out

    def bodies_used(self) -> set[int]:
        moved = {b for f in self._follower_bodies for b in self._subtree[f]}
        parents = {self.spec.body(f).parent for f in self._follower_bodies} - {None}
        return self.paths.bodies_used() | {self._body_index[b] for b in moved | parents}

    def repose(self, R, p, q, c=None):
        """Body poses with follower bodies (and their subtrees) moved to their true poses (copies)."""
        if not self._follower_bodies:
            return R, p
        R, p = R.copy(), p.copy()
        c = self.source.values(q)[0] if c is None else c
        for name in self._follower_bodies:
            Rx, px, _ = self._walk(name, R, p, q, c)
            ib = self._body_index[name]
            dR = Rx @ R[ib].T
            dp = px - dR @ p[ib]
            for other in self._subtree[name]:
                i = self._body_index[other]
                R[i], p[i] = dR @ R[i], dR @ p[i] + dp
        return R, p

    def _walk(self, name, R, p, q, c):
        """Pose of body `name` from its parent's pose through each of its joints, and each joint's
        world (axis, origin) on the way."""
        body = self.spec.body(name)
        if body.parent is None:
            Rx, px = np.eye(3), np.zeros(3)
        else:
            ip = self._body_index[body.parent]
            Rx, px = R[ip], p[ip]
        px = Rx @ body.pos + px
        Rx = Rx @ quat_matrix(body.quat)
        axes = {}
        for j in self._body_joints[name]:
            if j.name in self._plant_joints:
                k = self._plant_joints[j.name]
                value = q[k] / self._coords[k].sign
            elif j.name in self._follower_index:
                value = j.function.at(c[self.source.index[j.coordinate]])
            else:
                value = self._fixed[j.name]
            axis_w, origin_w = Rx @ j.axis, Rx @ j.anchor + px
            axes[j.name] = (axis_w, origin_w)
            if j.kind == "slide":
                px = px + axis_w * value
            else:
                Rj = _rotation(axis_w, value)
                px = origin_w + Rj @ (px - origin_w)
                Rx = Rj @ Rx
        return Rx, px, axes

    def _follower_axes(self, R, p, joint_axes, joint_origins, q, c):
        """World axes of the follower joints; plant joints on follower bodies get theirs too."""
        nf = len(self.followers)
        f_axes, f_origins = np.zeros((nf, 3)), np.zeros((nf, 3))
        for name in self._follower_bodies:
            for joint, (axis_w, origin_w) in self._walk(name, R, p, q, c)[2].items():
                if joint in self._follower_index:
                    f_axes[self._follower_index[joint]], f_origins[self._follower_index[joint]] = axis_w, origin_w
                elif joint in self._plant_joints:
                    k = self._plant_joints[joint]
                    joint_axes[k], joint_origins[k] = self._coords[k].sign * axis_w, origin_w
        return f_axes, f_origins

    def coordinate_values(self, q) -> np.ndarray:
        """The model's coordinates (in its own units) at plant positions q."""
        return self.source.values(q)[0]

    def path_state(self, R, p, q, joint_frames, v=None) -> PathState:
        """PathState at the plant's body poses R, p and positions q (velocities v).

        `joint_frames(R, p)` gives the plant joints' world axes and points from body poses.
        """
        c, dc = self.source.values(q)
        R, p = self.repose(R, p, q, c)
        joint_axes, joint_origins = joint_frames(R, p)
        f_axes, f_origins = self._follower_axes(R, p, joint_axes, joint_origins, q, c)
        site_local = site_active = site_dw = None
        if self._conditional:
            site_active = np.ones(len(self.spec.sites), dtype=bool)
            for i in self._conditional:
                coord, lo, hi = self.spec.sites[i].condition
                value = c[self.source.index[coord]]
                site_active[i] = lo - _CONDITION_TOLERANCE <= value <= hi + _CONDITION_TOLERANCE
        if self._moving:
            site_local = self.paths.site_local.copy()
            site_dw = np.zeros((len(self.spec.sites), 3, self.nq))
            for i in self._moving:
                dlocal = np.zeros((3, self.nq))
                for axis, (coord, f) in enumerate(self.spec.sites[i].motion):
                    x = c[self.source.index[coord]] if coord else 0.0
                    site_local[i, axis] = f.at(x)
                    if coord:
                        dlocal[axis] = f.at(x, 1) * dc[self.source.index[coord]]
                site_dw[i] = R[self._site_body[i]] @ dlocal
        axes = np.vstack([joint_axes, f_axes])
        origins = np.vstack([joint_origins, f_origins])
        lengths, grad, grad_q = self.paths.compute(R, p, axes, origins, site_local, site_active, site_dw)
        total = grad[:, :self.nq] + grad_q
        if self.followers:
            G = np.array([j.function.at(c[self.source.index[j.coordinate]], 1) * dc[self.source.index[j.coordinate]]
                          for j in self.followers])
            total = total + grad[:, self.nq:] @ G
        state = PathState(lengths=lengths, moment_arms=-total)
        if v is not None:
            state.velocities = total @ np.asarray(v, dtype=float)
        return state
