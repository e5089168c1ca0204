"""What is drawn, as numbers: rigid segments, muscle polylines (with wrap arcs) and their motion.

A segment is a set of plant bodies welded together (e.g. lumbar1 with the thorax and head);
it is drawn as one scene node whose world pose changes from frame to frame. A muscle is a
polyline through its path sites; where it wraps, the polyline follows the surface from one
tangent point to the other in `ARC_CHORDS` chords. Path sites move rigidly with their
segment, so only the wrap points (tangent points and arcs) vary within a segment's frame.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

ARC_CHORDS = 6  # chords per wrapped arc
ARC_POINTS = ARC_CHORDS + 1  # points per wrap, tangent points included


@dataclass(frozen=True)
class Segment:
    """Bodies welded together: drawn at the world pose of `body` (a plant body index)."""

    name: str
    body: int
    members: tuple[int, ...]


@dataclass
class Motion:
    """Frames of a drawing: segment poses and the world points of every wrap."""

    segment_R: np.ndarray  # (n_frames, n_segments, 3, 3)
    segment_p: np.ndarray  # (n_frames, n_segments, 3)
    wrap_points: np.ndarray  # (n_frames, n_wraps, ARC_POINTS, 3)

    @property
    def moving_segments(self) -> np.ndarray:
        """Indices of the segments whose pose changes over the frames."""
        moves = np.ptp(self.segment_R, axis=0).max(axis=(1, 2)) + np.ptp(self.segment_p, axis=0).max(axis=1)
        return np.flatnonzero(moves > 1e-12)


class Drawing:
    """Segments and muscle polylines of a TrunkModel, and their motion for coordinate histories."""

    def __init__(self, model):
        self.model = model
        plant = getattr(model.plant, "full", model.plant)  # the rhythm's CoupledPlant: the joints' plant (welds)
        names = model.body_names
        real = {b.name for b in model.spec.bodies}  # not the massless gimbals between joint axes
        seen, segments = set(), []
        for b in range(1, plant.num_bodies()):  # the world's weld group is drawn as a segment too
            if b in seen or names[b] not in real:
                continue
            group = sorted(int(x.index()) for x in plant.GetBodiesWeldedTo(plant.get_body(_index(b))))
            seen.update(group)
            root = group[0] if group[0] != 0 else group[1]
            segments.append(Segment(names[root].replace(" ", "_"), root, tuple(g for g in group if g != 0)))
        self.segments = tuple(segments)
        self.segment_of = {m: i for i, s in enumerate(segments) for m in s.members}
        self._layout = model.path_layout
        self._context = model.plant.CreateDefaultContext()
        self._all_bodies = range(plant.num_bodies())

    # ---- per pose -------------------------------------------------------------------
    def poses(self, q) -> tuple[np.ndarray, np.ndarray]:
        """World rotations and positions of all plant bodies at q."""
        self.model.plant.SetPositions(self._context, self.model.check_q(q, check_range=False))
        return self.model.body_poses(self._context, self._all_bodies)

    def frame(self, q) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Segment rotations (n_segments, 3, 3), positions (n_segments, 3) and wrap points at q."""
        motion = self.motion(np.asarray(q, dtype=float)[None])
        return motion.segment_R[0], motion.segment_p[0], motion.wrap_points[0]

    def motion(self, q_history) -> Motion:
        """Segment poses and wrap points for every row of q_history (n_frames, n_q)."""
        lay, root = self._layout, [s.body for s in self.segments]
        R_seg, p_seg, tangents, lengths, centre, axis = [], [], [], [], [], []
        for q in np.asarray(q_history, dtype=float):
            R, p = self.poses(q)
            points = self.model.path_points(q)
            R_seg.append(R[root])
            p_seg.append(p[root])
            tangents.append(points.tangents)
            lengths.append(points.wrap_lengths)
            centre.append(np.einsum("wij,wj->wi", R[lay.wrap_body], lay.wrap_pos) + p[lay.wrap_body])
            axis.append(np.einsum("wij,wj->wi", R[lay.wrap_body], lay.wrap_rot[:, :, 2]))
        arcs = wrap_arcs(np.array(tangents), np.array(lengths), np.array(centre), np.array(axis), lay.wrap_radius, lay.wrap_cylinder)
        return Motion(np.array(R_seg), np.array(p_seg), arcs)

    def polylines(self, q) -> list[np.ndarray]:
        """World points of every muscle's polyline at q (for a still picture or a live view)."""
        R_seg, p_seg, arcs = self.frame(q)
        return [np.array([R_seg[v[0]] @ v[1:] + p_seg[v[0]] if v[0] >= 0 else arcs.reshape(-1, 3)[int(v[1])]
                          for v in verts]) for verts in self.vertices()]

    # ---- layout -----------------------------------------------------------------------
    def vertices(self) -> list[list[list[float]]]:
        """Per muscle its polyline vertices: [segment, x, y, z] for a site (coordinates in the
        segment frame) or [-1, k] for row k of the flattened wrap points (n_wraps * ARC_POINTS)."""
        lay = self._layout
        R0, p0 = self.poses(np.zeros(self.model.plant.num_positions()))
        out = []
        for route in lay.routes:
            verts = []
            for kind, i in route:
                if kind == "wrap":
                    verts += [[-1, i * ARC_POINTS + k] for k in range(ARC_POINTS)]
                    continue
                body = int(lay.site_body[i])
                s = self.segment_of[body]
                root = self.segments[s].body
                world = R0[body] @ lay.site_local[i] + p0[body]
                verts.append([s, *(R0[root].T @ (world - p0[root]))])
            out.append(verts)
        return out


def wrap_arcs(tangents, wrap_lengths, centre, axis, radius, cylinder, n_points: int = ARC_POINTS) -> np.ndarray:
    """Points along each wrapped arc, tangent point to tangent point: (..., n_wraps, n_points, 3).

    tangents (..., n_wraps, 2, 3), wrap_lengths (..., n_wraps) (-1: not wrapped, all points at
    the first tangent point), centre and cylinder axis (..., n_wraps, 3) in the world; radius and
    cylinder (n_wraps,). A sphere's arc lies in the plane of its centre and tangent points, a
    cylinder's is a helix; the arc goes the way round whose length is the wrap length.
    """
    t0, t1 = tangents[..., 0, :], tangents[..., 1, :]
    d0, d1 = t0 - centre, t1 - centre
    normal = np.cross(d0, d1)
    normal /= np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-15)
    n = np.where(cylinder[:, None], axis, normal)
    h0, h1 = np.sum(d0 * n, axis=-1), np.sum(d1 * n, axis=-1)
    r0, r1 = d0 - h0[..., None] * n, d1 - h1[..., None] * n
    angle = np.arctan2(np.sum(n * np.cross(r0, r1), axis=-1), np.sum(r0 * r1, axis=-1))
    planar = np.where(cylinder, np.sqrt(np.maximum(wrap_lengths**2 - (h1 - h0) ** 2, 0.0)), wrap_lengths) / radius
    other_way = angle - np.sign(angle) * 2 * np.pi
    angle = np.where(np.abs(np.abs(other_way) - planar) < np.abs(np.abs(angle) - planar), other_way, angle)
    s = np.linspace(0.0, 1.0, n_points)
    phi = angle[..., None] * s
    u0 = r0 / np.maximum(np.linalg.norm(r0, axis=-1, keepdims=True), 1e-15)
    v0 = np.cross(n, u0)
    points = (centre[..., None, :] + radius[:, None, None] * (np.cos(phi)[..., None] * u0[..., None, :]
                                                              + np.sin(phi)[..., None] * v0[..., None, :])
              + (h0[..., None] + s * (h1 - h0)[..., None])[..., None] * n[..., None, :])
    return np.where((wrap_lengths < 0)[..., None, None], t0[..., None, :], points)


def _index(i: int):
    from pydrake.multibody.tree import BodyIndex

    return BodyIndex(i)
