"""Excitation: feed-forward plus feedback channels, and the thesis' stretch reflex (seed eq. 3.2).

The mixer is a small Diagram of Drake's compiled primitives (no Python per evaluation).
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import Diagram, DiagramBuilder, LeafSystem
from pydrake.systems.primitives import Adder, Saturation
from trunk_drake.systems.weak import weak


def gains_by_group(model, values: dict[str, float], default: float = 0.0) -> np.ndarray:
    """Per-muscle gains from per-group values, e.g. {"sacrospinalis": 0.13, ...}."""
    groups = model.groups
    unknown = set(values) - set(groups)
    if unknown:
        raise ValueError(f"unknown muscle groups {sorted(unknown)}; groups of this model: {sorted(groups)}")
    gains = np.full(model.n_muscles, float(default))
    index = {n: i for i, n in enumerate(model.muscles)}
    for group, value in values.items():
        if not np.isfinite(value) or value < 0:
            raise ValueError(f"reflex gain of group {group!r} must be finite and >= 0, got {value}")
        gains[[index[m] for m in groups[group]]] = value
    return gains


def group_gains(model, value) -> dict[str, float]:
    """Per-group gains (every group) from a scalar, a per-group dict (missing groups: 0), or a
    per-muscle array that is constant within each group (the inverse of gains_by_group)."""
    if isinstance(value, dict):
        return {g: float(value.get(g, 0.0)) for g in model.groups}
    arr = np.broadcast_to(np.asarray(value, float), (model.n_muscles,))
    index = {m: i for i, m in enumerate(model.muscles)}
    out = {}
    for g, members in model.groups.items():
        values = arr[[index[m] for m in members]]
        if np.ptp(values) > 1e-12:
            raise ValueError(f"reflex gains differ within group {g!r}: give one gain per muscle group")
        out[g] = float(values[0])
    return out


class StretchReflex(LeafSystem):
    """The Muscle Fiber Stretch Controller: feedback = kp (l_n - l_d)+ + kv (dl_n)+.

    Inputs ``normalized_fiber_length`` (l / l_opt) and ``normalized_fiber_velocity``
    (v / (v_max l_opt)); output ``feedback`` (n). ``kp``, ``kv``, ``l_desired`` are per-muscle
    arrays (or scalars). A transport delay is added by the diagram builder on the inputs.
    (A LeafSystem, not compiled primitives: the stability analysis rescales ``kp`` and ``kv`` in place.)
    """

    def __init__(self, n: int, kp, kv, l_desired=1.0):
        super().__init__()
        self.kp = np.broadcast_to(np.asarray(kp, float), (n,)).copy()
        self.kv = np.broadcast_to(np.asarray(kv, float), (n,)).copy()
        self.l_desired = np.broadcast_to(np.asarray(l_desired, float), (n,)).copy()
        self._ln = self.DeclareVectorInputPort("normalized_fiber_length", n)
        self._vn = self.DeclareVectorInputPort("normalized_fiber_velocity", n)
        self.DeclareVectorOutputPort("feedback", n, weak(self._calc))

    def feedback(self, norm_length, norm_velocity) -> np.ndarray:
        return self.kp * np.maximum(norm_length - self.l_desired, 0.0) + self.kv * np.maximum(norm_velocity, 0.0)

    def _calc(self, context, output):
        output.SetFromVector(self.feedback(self._ln.Eval(context), self._vn.Eval(context)))


class ExcitationMixer(Diagram):
    """Excitation u = clip(feed-forward + sum of feedback channels, u_min, 1).

    Inputs ``feedforward`` and ``feedback_0`` ... ``feedback_{k-1}`` (n each); output ``excitation``.
    """

    def __init__(self, n: int, n_feedback: int, min_excitation: float = 0.01):
        super().__init__()
        self.min_excitation = float(min_excitation)
        b = DiagramBuilder()
        total = b.AddNamedSystem("sum", Adder(1 + n_feedback, n))
        clip = b.AddNamedSystem("clip", Saturation(np.full(n, self.min_excitation), np.ones(n)))
        b.Connect(total.get_output_port(), clip.get_input_port())
        for k, name in enumerate(["feedforward", *(f"feedback_{j}" for j in range(n_feedback))]):
            b.ExportInput(total.get_input_port(k), name)
        b.ExportOutput(clip.get_output_port(), "excitation")
        b.BuildInto(self)
