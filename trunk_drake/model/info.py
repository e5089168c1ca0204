"""Summary of a trunk model: coordinates, muscles per group, masses, upper-body centre of mass."""

from __future__ import annotations

import numpy as np

from trunk_drake.data import load_toml
from trunk_drake.model.levels import LEVEL_BODIES
from trunk_drake.model.plant import rhythm_spec

THESIS_COM_ANTERIOR_TO_L4 = 0.091  # m, seed thesis section 3.2.3 (Schmid et al.'s full-body model)


def _subtree(spec, root: str) -> list[str]:
    out, todo = [], [root]
    while todo:
        name = todo.pop()
        out.append(name)
        todo.extend(spec.children(name))
    return out


def model_info(model) -> dict:
    """Plain-data description of `model` at its neutral posture (SI units)."""
    plant, spec = model.plant, model.spec
    context = plant.CreateDefaultContext()
    groups = model.groups
    rhythm = None
    if model.coupling is not None:
        source = rhythm_spec(spec)
        rhythm = {"coordinate": model.coordinates[-1], "driver": source.driver, "source": source.source,
                  "level_shares": dict(zip(model.levels, model.level_matrix[:, -1].tolist())),
                  "routing": {c.name: float(g) for c, g in zip(model.joint_info, model.coupling[:, -1]) if c.name not in model.levels and g}}
    return {
        "model": spec.name,
        "source": spec.source,
        "dofs": model.dofs,
        "coordinates": model.coordinates,
        "rhythm": rhythm,
        "n_muscles": model.n_muscles,
        "muscles_per_group": {g: len(m) for g, m in groups.items()},
        "absent_thesis_groups": load_toml("muscle_groups.toml")["absent"],
        "total_mass_kg": float(plant.CalcTotalMass(context)),
        "upper_body": _upper_body(plant, context, spec),
    }


def _upper_body(plant, context, spec) -> dict | None:
    """Mass and centre of mass of everything above the top lumbar vertebra, relative to L4, along the pelvis' axes
    (x anterior, y superior); None for a model without the five lumbar vertebrae or without mass above them."""
    levels = spec.level_bodies or LEVEL_BODIES
    if len(levels) != len(LEVEL_BODIES) or not set(levels) <= {b.name for b in spec.bodies}:
        return None
    pelvis = plant.EvalBodyPoseInWorld(context, plant.GetBodyByName(spec.pelvis)).rotation().matrix()
    anterior, superior = pelvis[:, 0], pelvis[:, 1]
    upper = [b for child in spec.children(levels[-1]) for b in _subtree(spec, child)]
    masses = np.array([spec.body(b).mass for b in upper])
    if masses.sum() <= 0.0:
        return None
    coms = np.array([plant.EvalBodyPoseInWorld(context, plant.GetBodyByName(b)).multiply(spec.body(b).com) for b in upper])
    com = masses @ coms / masses.sum()
    l4 = plant.EvalBodyPoseInWorld(context, plant.GetBodyByName(levels[1]))
    rel_joint, rel_body = com - l4.translation(), com - l4.multiply(spec.body(levels[1]).com)
    return {
        "bodies": upper,
        "mass_kg": float(masses.sum()),
        "com_anterior_of_L4_L5_joint_m": float(rel_joint @ anterior),
        "com_superior_of_L4_L5_joint_m": float(rel_joint @ superior),
        "com_anterior_of_L4_body_centre_m": float(rel_body @ anterior),
        "thesis_com_anterior_of_L4_m": THESIS_COM_ANTERIOR_TO_L4,
        "agrees_with_thesis": bool(abs(rel_body @ anterior - THESIS_COM_ANTERIOR_TO_L4) < 0.01),
    }


def format_model_info(info: dict) -> str:
    ub = info["upper_body"]
    lines = [
        f"model {info['model']} ({info['source']}), configuration {info['dofs']!r}",
        f"coordinates ({len(info['coordinates'])}): {', '.join(info['coordinates'])}",
        *([f"rhythm ({info['rhythm']['source']}): {info['rhythm']['coordinate']} = sum of the level angles; shares "
           + ", ".join(f"{k} {v:.3f}" for k, v in info['rhythm']['level_shares'].items())
           + "".join(f"; routing {k} {v:+.4f} rad/rad" for k, v in info['rhythm']['routing'].items())] if info.get("rhythm") else []),
        f"muscles: {info['n_muscles']}",
        *(f"  {g:20s} {n:3d}" for g, n in info["muscles_per_group"].items()),
        "absent thesis groups: " + "; ".join(f"{g} ({why})" for g, why in info["absent_thesis_groups"].items()),
        f"total mass {info['total_mass_kg']:.2f} kg",
    ]
    if ub is None:
        return "\n".join([*lines, "upper body: not summarised (the model has no bodies lumbar5 ... lumbar1, or no mass above lumbar1)"])
    return "\n".join([
        *lines,
        f"upper body ({', '.join(ub['bodies'])}) {ub['mass_kg']:.2f} kg",
        f"upper-body centre of mass: {_cm(ub['com_anterior_of_L4_L5_joint_m'], 'anterior', 'posterior')} and "
        f"{_cm(ub['com_superior_of_L4_L5_joint_m'], 'superior', 'inferior')} to the L4/L5 joint centre; "
        f"{_cm(ub['com_anterior_of_L4_body_centre_m'], 'anterior', 'posterior')} to the L4 body centre",
        f"  thesis (Schmid et al. model): {_cm(ub['thesis_com_anterior_of_L4_m'], 'anterior', 'posterior')} to L4 -> "
        + ("agrees (within 1 cm)" if ub["agrees_with_thesis"] else f"does NOT agree: {info['model']} has no arms and a posterior lumped upper body"),
    ])


def _cm(metres: float, positive: str, negative: str) -> str:
    """A signed distance in words: "1.1 cm posterior" for -0.011 with ("anterior", "posterior")."""
    return f"{100 * abs(metres):.1f} cm {positive if metres >= 0 else negative}"
