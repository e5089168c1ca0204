"""Figures people look at: simulation overview (more figures live with their analyses)."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402


def plot_simulation(result, path) -> Path:
    """Platform/pelvis motion, lumbar rotation per level and in total, and muscle activity by group."""
    from trunk_drake.data import load_toml

    t = result.time
    fig, axes = plt.subplots(4, 1, figsize=(9, 10), sharex=True)
    axes[0].plot(t, 100 * result.platform[:, 0], color="0.5", label="platform")
    if "pelvis_tx" in result.coordinates:
        axes[0].plot(t, 100 * result.coordinate("pelvis_tx"), "k", lw=1, label="pelvis")
    axes[0].set_ylabel("displacement (cm)")
    axes[0].legend(loc="upper right")
    rot = np.degrees(result.lumbar_rotation - result.lumbar_rotation[0])
    axes[1].plot(t, rot, "k")
    axes[1].set_ylabel("lumbar rotation (deg)\n(flexion +)")
    for name in [c for c in result.coordinates if c.endswith("_FE")]:
        axes[2].plot(t, np.degrees(result.coordinate(name)), lw=1, label=name)
    axes[2].set_ylabel("joint angle (deg)")
    axes[2].legend(loc="upper right", ncol=5, fontsize=7)
    groups = load_toml("muscle_groups.toml")["groups"]
    for group, prefixes in groups.items():
        idx = [i for i, m in enumerate(result.muscles) if any(m.startswith(p) for p in prefixes)]
        if idx:
            axes[3].plot(t, result.activation[:, idx].mean(axis=1), lw=1, label=group)
    axes[3].set_ylabel("mean activation")
    axes[3].set_xlabel("time (s)")
    axes[3].legend(loc="upper right", ncol=2, fontsize=7)
    fig.suptitle(f"trunk-drake simulation: {result.sim_time_s:.1f} s in {result.wall_time_s:.1f} s wall "
                 f"(real-time factor {result.real_time_factor:.1f})")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
