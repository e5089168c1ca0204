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


def plot_fit(result, out_dir) -> dict:
    """Time-domain fit (seed Fig. 4.14), FRF of data and model (Fig. 4.15), convergence."""
    out = Path(out_dir)
    files = {}
    n = len(result.series)
    fig, axes = plt.subplots(n, 1, figsize=(9, 2.6 * n), squeeze=False)
    for ax, (name, s) in zip(axes[:, 0], result.series.items()):
        vaf = result.vaf[name].get(s["output"])
        ax.plot(s["time"], np.degrees(s["data"]), color="0.6", lw=1, label="data")
        ax.plot(s["time"], np.degrees(s["model"]), "k", lw=1,
                label="model (VAF undefined: constant target)" if vaf is None else f"model (VAF {100 * vaf:.1f} %)")
        ax.set_title(Path(name).name, fontsize=9)
        ax.set_ylabel(f"{s['output']} (deg)")
        ax.legend(loc="upper right", fontsize=8)
    axes[-1, 0].set_xlabel("time (s)")
    fig.tight_layout()
    files["time_plot"] = out / "fit_time.png"
    fig.savefig(files["time_plot"], dpi=110)
    plt.close(fig)

    if result.frf:
        fig, (ax_g, ax_p) = plt.subplots(2, 1, figsize=(7, 6), sharex=True)
        for k, (name, f) in enumerate(result.frf.items()):
            color = f"C{k}"
            freq = f["frequencies"]
            ax_g.loglog(freq, np.degrees(np.abs(f["data"])), "o", color=color, ms=4, mfc="none", label=f"data {Path(name).stem}")
            ax_g.fill_between(freq, np.degrees(f["data_lower"]), np.degrees(f["data_upper"]), color=color, alpha=0.15)
            ax_g.loglog(freq, np.degrees(np.abs(f["model"])), "-", color=color, label="model")
            ax_p.semilogx(freq, np.degrees(np.unwrap(np.angle(f["data"]))), "o", color=color, ms=4, mfc="none")
            ax_p.semilogx(freq, np.degrees(np.unwrap(np.angle(f["model"]))), "-", color=color)
        ax_g.set_ylabel("gain (deg/m)")
        ax_g.legend(fontsize=7)
        ax_p.set_ylabel("phase (deg)")
        ax_p.set_xlabel("frequency (Hz)")
        fig.suptitle("lumbar rotation / platform displacement")
        fig.tight_layout()
        files["frf_plot"] = out / "fit_frf.png"
        fig.savefig(files["frf_plot"], dpi=110)
        plt.close(fig)

    fig, ax = plt.subplots(figsize=(6, 3.5))
    for start in sorted({h["start"] for h in result.history}):
        costs = [h["cost"] for h in result.history if h["start"] == start]
        ax.semilogy(np.minimum.accumulate(costs), label=f"start {start + 1}")
    ax.set_xlabel("evaluated gain sets")
    ax.set_ylabel("best cost so far")
    ax.legend(fontsize=8)
    files["convergence_plot"] = save(fig, out / "fit_convergence.png")
    return files


def save(fig, path) -> Path:
    """Lay out, write (110 dpi) and close a figure; returns its path."""
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return Path(path)


def plot_stability(result, out_dir) -> dict:
    """Eigenvalue map (characteristic roots, the one-sided branches of a real mode) and the
    least-stable mode shapes (static and dynamic) over the model's coordinates."""
    out = Path(out_dir)
    files = {}
    dyn = result.dynamic
    if dyn is not None:
        fig, ax = plt.subplots(figsize=(6.5, 4.5))
        roots = dyn.roots[np.isfinite(dyn.roots)]
        ax.plot(roots.real, roots.imag / (2 * np.pi), "x", color="0.4", label="roots (central linearisation)")
        for k, (name, s) in enumerate(dyn.branches.items()):
            ax.plot(s.real, s.imag / (2 * np.pi), "o", mfc="none", ms=9, color=f"C{k}", label=f"rightmost, {name}")
        ax.axvline(0.0, color="k", lw=0.8)
        span = max(5.0, 3 * abs(dyn.margin))
        ax.set_xlim(-8 * span, 2 * span)
        ax.set_xlabel("real part (1/s)")
        ax.set_ylabel("imaginary part (Hz)")
        ax.set_title(f"closed-loop roots: {'stable' if dyn.stable else 'unstable'}, margin {dyn.margin:+.3g} 1/s", fontsize=10)
        ax.legend(fontsize=7)
        files["roots_plot"] = save(fig, out / "stability_roots.png")
    fig, ax = plt.subplots(figsize=(6.5, 3.8))
    x = np.arange(len(result.coordinates))
    shapes = {f"static (index {result.static.stability_index:+.0f} Nm/rad)": result.static.least_stable_mode}
    if dyn is not None:
        shapes[f"dynamic ({dyn.mode_branch}, {dyn.rightmost.real:+.3g} 1/s)"] = dyn.mode
    width = 0.8 / len(shapes)
    for k, (label, shape) in enumerate(shapes.items()):
        ax.bar(x + (k - (len(shapes) - 1) / 2) * width, shape, width, label=label)
    ax.axhline(0.0, color="k", lw=0.8)
    ax.set_xticks(x, result.coordinates, rotation=45 if len(x) > 6 else 0, fontsize=8)
    ax.set_ylabel("least-stable mode (largest = 1)")
    ax.legend(fontsize=8)
    files["mode_plot"] = save(fig, out / "stability_mode.png")
    return files
