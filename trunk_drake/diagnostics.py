"""Computation-time diagnostics (seed Table 4.1, automated) and 'oscillating' muscles."""

from __future__ import annotations

import numpy as np

from trunk_drake.simulation import simulate

# the thesis' order of adding muscle groups (Table 4.1), restricted to MyoTorso's groups
THESIS_GROUP_ORDER = ("sacrospinalis", "transversospinalis", "quadratus_lumborum", "internal_oblique",
                      "external_oblique", "rectus_abdominis", "psoas_major")


def steps_by_group(model, duration: float = 1.0, order=THESIS_GROUP_ORDER, **simulate_options) -> list[dict]:
    """Integrator work as muscle groups are added one by one (intrinsic properties only).

    Each row simulates `duration` seconds with the groups so far switched on (others
    masked off) and reports steps, derivative evaluations and wall time. Default
    settings: no perturbation, no reflexes, minimum activation, thesis bushings.
    """
    groups = model.groups
    unknown = [g for g in order if g not in groups]
    if unknown:
        raise ValueError(f"unknown muscle groups {unknown}; groups: {sorted(groups)}")
    options = {"perturbation": None, **simulate_options}
    index = {m: i for i, m in enumerate(model.muscles)}
    mask = np.zeros(model.n_muscles)
    rows = []
    for group in (None, *order):
        if group is not None:
            mask[[index[m] for m in groups[group]]] = 1.0
        result = simulate(model, duration=duration, muscle_mask=mask.copy(), **options)
        rows.append({
            "added_group": group or "(no muscles)",
            "n_muscles": int(mask.sum()),
            "steps": result.stats["steps"],
            "derivative_evaluations": result.stats["derivative_evaluations"],
            "wall_time_s": result.wall_time_s,
        })
    return rows


def extreme_muscles(result, length_range=(0.5, 1.5), velocity_limit: float = 0.5, top: int = 10) -> list[dict]:
    """Muscles whose normalised fiber length leaves `length_range` or whose normalised fiber
    velocity exceeds `velocity_limit` (the thesis' 'oscillating' muscles), worst first."""
    ln, vn = result.normalized_fiber_length, result.normalized_fiber_velocity
    peak_v = np.abs(vn).max(axis=0)
    out_of_range = (ln.min(axis=0) < length_range[0]) | (ln.max(axis=0) > length_range[1])
    flagged = np.flatnonzero(out_of_range | (peak_v > velocity_limit))
    sign_changes = (np.diff(np.sign(vn), axis=0) != 0).sum(axis=0)
    rows = [{
        "muscle": result.muscles[i],
        "min_normalized_length": float(ln[:, i].min()),
        "max_normalized_length": float(ln[:, i].max()),
        "peak_normalized_velocity": float(peak_v[i]),
        "velocity_sign_changes": int(sign_changes[i]),
    } for i in flagged]
    return sorted(rows, key=lambda r: -r["peak_normalized_velocity"])[:top]
