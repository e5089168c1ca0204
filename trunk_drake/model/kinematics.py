"""World poses of the plant's bodies and joint axes from q, compiled: the kinematics the muscle paths need.

The plant's tree (weld, revolute and prismatic joints, as `trunk_drake.model.plant` builds it)
is read once from the finalized MultibodyPlant: per body its parent, the fixed pose of the
joint's frame F on the parent, the joint's axis and coordinate and the fixed pose of the
joint's frame M on the child. Then X_WB = X_WP X_PF X_FM(q) X_MB for every body in tree order,
in one numba call (the plant's own kinematics would cost a Context update and a Python
object per body at every derivative evaluation). Tests compare the poses with the plant's.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from pydrake.multibody.tree import BodyIndex, JointIndex

WELD, REVOLUTE, PRISMATIC = 0, 1, 2
_KINDS = {"weld": WELD, "revolute": REVOLUTE, "prismatic": PRISMATIC}


def _matrix34(X) -> np.ndarray:
    return np.asarray(X.GetAsMatrix34(), dtype=float)


class TreeKinematics:
    """Forward kinematics of a finalized plant whose joints are welds, revolutes and prismatics,
    and the world axes and origins of the joints of `coordinates` (joint names, in the order of q)."""

    def __init__(self, plant, coordinates):
        n_bodies = plant.num_bodies()
        inboard = {}
        for j in range(plant.num_joints()):
            joint = plant.get_joint(JointIndex(j))
            kind = _KINDS.get(joint.type_name())
            if kind is None:
                raise ValueError(f"joint {joint.name()!r} is a {joint.type_name()} joint; the muscle-path kinematics "
                                 "handle weld, revolute and prismatic joints only")
            child = int(joint.frame_on_child().body().index())
            X_FM = _matrix34(joint.X_FM()) if kind == WELD else np.hstack([np.eye(3), np.zeros((3, 1))])
            axis = np.zeros(3) if kind == WELD else np.asarray(
                joint.revolute_axis() if kind == REVOLUTE else joint.translation_axis(), dtype=float)
            X_BM = joint.frame_on_child().GetFixedPoseInBodyFrame()
            inboard[child] = (int(joint.frame_on_parent().body().index()), kind, joint.position_start() if kind else -1,
                              _matrix34(joint.frame_on_parent().GetFixedPoseInBodyFrame()), X_FM, axis,
                              _matrix34(X_BM.inverse()))
        order, placed = [], {0}  # tree order: parents first; body 0 is the world
        while len(order) < len(inboard):
            ready = [b for b in sorted(inboard) if b not in placed and inboard[b][0] in placed]
            if not ready:
                raise ValueError(f"bodies {sorted(set(inboard) - placed)} are not connected to the world by joints")
            order += ready
            placed |= set(ready)
        floating = set(range(1, n_bodies)) - placed
        if floating:
            names = [plant.get_body(BodyIndex(b)).name() for b in sorted(floating)]
            raise ValueError(f"bodies {names} have no inboard joint; the muscle-path kinematics need a jointed tree")
        rows = [inboard[b] for b in order]
        self.n_bodies = n_bodies
        self._body = np.array(order, dtype=np.int64)
        self._parent = np.array([r[0] for r in rows], dtype=np.int64)
        self._kind = np.array([r[1] for r in rows], dtype=np.int64)
        self._q_index = np.array([r[2] for r in rows], dtype=np.int64)
        self._X_PF = np.array([r[3] for r in rows]).reshape(-1, 3, 4)
        self._X_FM = np.array([r[4] for r in rows]).reshape(-1, 3, 4)
        self._axis = np.array([r[5] for r in rows]).reshape(-1, 3)
        self._X_MB = np.array([r[6] for r in rows]).reshape(-1, 3, 4)
        self.moves = np.zeros((n_bodies, plant.num_positions()))  # 1 where coordinate k moves body b
        for b, (parent, kind, q_index, *_) in zip(order, rows):
            self.moves[b] = self.moves[parent]
            if kind != WELD:
                self.moves[b, q_index] = 1.0
        bodies = [plant.get_body(BodyIndex(b)) for b in range(n_bodies)]
        self._mass = np.array([b.default_mass() for b in bodies], dtype=float)
        self._com = np.array([b.default_com() for b in bodies], dtype=float).reshape(-1, 3)
        joints = [plant.GetJointByName(name) for name in coordinates]
        self._revolute = np.array([j.type_name() == "revolute" for j in joints], dtype=np.bool_)
        frames = [j.frame_on_child().GetFixedPoseInBodyFrame() for j in joints]
        self.joint_body = np.array([int(j.frame_on_child().body().index()) for j in joints], dtype=np.int64)
        self._joint_axis = np.array([X.rotation().matrix() @ np.asarray(j.revolute_axis() if j.type_name() == "revolute"
                                                                          else j.translation_axis())
                                     for j, X in zip(joints, frames)], dtype=float).reshape(-1, 3)
        self._joint_anchor = np.array([X.translation() for X in frames], dtype=float).reshape(-1, 3)

    def poses(self, q) -> tuple[np.ndarray, np.ndarray]:
        """Rotations (n_bodies, 3, 3) and positions (n_bodies, 3) of every body in the world."""
        return _poses(np.ascontiguousarray(q, dtype=float), self.n_bodies, self._body, self._parent, self._kind,
                      self._q_index, self._X_PF, self._X_FM, self._axis, self._X_MB)

    def frames(self, q) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Body rotations and positions (see `poses`), and the world axis (n_coords, 3) of every
        coordinate's joint and a point on it (its child frame's origin)."""
        R, p = self.poses(q)
        axes, origins = _joint_frames(R, p, self.joint_body, self._joint_axis, self._joint_anchor)
        return R, p, axes, origins

    def mass_weighted_com_jacobian(self, q, direction) -> np.ndarray:
        """``M J_com^T d`` (n_coords,): the sum over bodies of m_b (d . dc_b/dq), with J_com the Jacobian
        of the centre of mass' velocity w.r.t. the generalized velocities (= qdot here) and d a world direction."""
        R, p, axes, origins = self.frames(q)
        return _com_direction(R, p, axes, origins, self._revolute, self.moves, self._mass, self._com,
                              np.asarray(direction, dtype=float))


@numba.njit(cache=True)
def _joint_frames(R, p, body, axis_B, anchor_B):
    n = body.shape[0]
    axes, origins = np.empty((n, 3)), np.empty((n, 3))
    for k in range(n):
        Rb = R[body[k]]
        for r in range(3):
            axes[k, r] = Rb[r, 0] * axis_B[k, 0] + Rb[r, 1] * axis_B[k, 1] + Rb[r, 2] * axis_B[k, 2]
            origins[k, r] = Rb[r, 0] * anchor_B[k, 0] + Rb[r, 1] * anchor_B[k, 1] + Rb[r, 2] * anchor_B[k, 2] + p[body[k], r]
    return axes, origins


@numba.njit(cache=True)
def _compose(Ra, pa, X, Rout, pout):
    """(Rout, pout) = (Ra, pa) * X for a 3x4 transform X."""
    for r in range(3):
        for c in range(3):
            Rout[r, c] = Ra[r, 0] * X[0, c] + Ra[r, 1] * X[1, c] + Ra[r, 2] * X[2, c]
        pout[r] = pa[r] + Ra[r, 0] * X[0, 3] + Ra[r, 1] * X[1, 3] + Ra[r, 2] * X[2, 3]


@numba.njit(cache=True)
def _poses(q, n_bodies, body, parent, kind, q_index, X_PF, X_FM, axis, X_MB):
    R = np.zeros((n_bodies, 3, 3))
    p = np.zeros((n_bodies, 3))
    for i in range(3):
        R[0, i, i] = 1.0
    X = np.empty((3, 4))
    RF, pF, RM, pM = np.empty((3, 3)), np.empty(3), np.empty((3, 3)), np.empty(3)
    for j in range(body.shape[0]):
        _compose(R[parent[j]], p[parent[j]], X_PF[j], RF, pF)
        if kind[j] == 1:  # revolute: Rodrigues' rotation about the unit axis
            a = axis[j]
            s, c = math.sin(q[q_index[j]]), math.cos(q[q_index[j]])
            for r in range(3):
                for k in range(3):
                    X[r, k] = (1.0 - c) * a[r] * a[k]
                X[r, 3] = 0.0
            X[0, 0] += c
            X[1, 1] += c
            X[2, 2] += c
            X[0, 1] -= s * a[2]
            X[1, 0] += s * a[2]
            X[0, 2] += s * a[1]
            X[2, 0] -= s * a[1]
            X[1, 2] -= s * a[0]
            X[2, 1] += s * a[0]
        elif kind[j] == 2:  # prismatic: translation along the axis
            for r in range(3):
                for k in range(3):
                    X[r, k] = 1.0 if r == k else 0.0
                X[r, 3] = axis[j, r] * q[q_index[j]]
        else:
            X[:, :] = X_FM[j]
        _compose(RF, pF, X, RM, pM)
        _compose(RM, pM, X_MB[j], R[body[j]], p[body[j]])
    return R, p


@numba.njit(cache=True)
def _com_direction(R, p, axes, origins, revolute, moves, mass, com_B, d):
    out = np.zeros(axes.shape[0])
    for b in range(mass.shape[0]):
        if mass[b] == 0.0:
            continue
        c = R[b] @ com_B[b] + p[b]
        for k in range(axes.shape[0]):
            if moves[b, k] == 0.0:
                continue
            a = axes[k]
            if revolute[k]:  # d . (a x (c - o))
                r0, r1, r2 = c[0] - origins[k, 0], c[1] - origins[k, 1], c[2] - origins[k, 2]
                out[k] += mass[b] * (d[0] * (a[1] * r2 - a[2] * r1) + d[1] * (a[2] * r0 - a[0] * r2) + d[2] * (a[0] * r1 - a[1] * r0))
            else:
                out[k] += mass[b] * (d[0] * a[0] + d[1] * a[1] + d[2] * a[2])
    return out
