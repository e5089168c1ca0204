"""Summary of a trunk model: coordinates, muscles per group, masses, upper-body centre of mass."""

from __future__ import annotations

import numpy as np

from trunk_drake.data import load_toml

UPPER_BODY_ROOT = "torso"  # MyoTorso lumps thorax, head and neck above L1 into this subtree
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
    pelvis = plant.EvalBodyPoseInWorld(context, plant.GetBodyByName("sacrum")).rotation().matrix()
    anterior, superior = pelvis[:, 0], pelvis[:, 1]

    upper = _subtree(spec, UPPER_BODY_ROOT)
    masses = np.array([spec.body(b).mass for b in upper])
    coms = np.array([plant.EvalBodyPoseInWorld(context, plant.GetBodyByName(b)).multiply(spec.body(b).com) for b in upper])
    com = masses @ coms / masses.sum()
    l4 = plant.EvalBodyPoseInWorld(context, plant.GetBodyByName("lumbar4"))
    joint_centre = l4.translation()
    body_centre = l4.multiply(spec.body("lumbar4").com)
    rel_joint, rel_body = com - joint_centre, com - body_centre

    groups = model.groups
    return {
        "model": spec.name,
        "source": spec.source,
        "dofs": model.dofs,
        "coordinates": model.coordinates,
        "n_muscles": model.n_muscles,
        "muscles_per_group": {g: len(m) for g, m in groups.items()},
        "absent_thesis_groups": load_toml("muscle_groups.toml")["absent"],
        "total_mass_kg": float(plant.CalcTotalMass(context)),
        "upper_body": {
            "bodies": upper,
            "mass_kg": float(masses.sum()),
            "com_anterior_of_L4_L5_joint_m": float(rel_joint @ anterior),
            "com_superior_of_L4_L5_joint_m": float(rel_joint @ superior),
            "com_anterior_of_L4_body_centre_m": float(rel_body @ anterior),
            "thesis_com_anterior_of_L4_m": THESIS_COM_ANTERIOR_TO_L4,
            "agrees_with_thesis": bool(abs(rel_body @ anterior - THESIS_COM_ANTERIOR_TO_L4) < 0.01),
        },
    }


def format_model_info(info: dict) -> str:
    ub = info["upper_body"]
    lines = [
        f"model {info['model']} ({info['source']}), configuration {info['dofs']!r}",
        f"coordinates ({len(info['coordinates'])}): {', '.join(info['coordinates'])}",
        f"muscles: {info['n_muscles']}",
        *(f"  {g:20s} {n:3d}" for g, n in info["muscles_per_group"].items()),
        "absent thesis groups: " + "; ".join(f"{g} ({why})" for g, why in info["absent_thesis_groups"].items()),
        f"total mass {info['total_mass_kg']:.2f} kg; upper body ({', '.join(ub['bodies'])}) {ub['mass_kg']:.2f} kg",
        f"upper-body centre of mass: {100 * ub['com_anterior_of_L4_L5_joint_m']:+.1f} cm anterior and "
        f"{100 * ub['com_superior_of_L4_L5_joint_m']:.1f} cm superior to the L4/L5 joint centre; "
        f"{100 * ub['com_anterior_of_L4_body_centre_m']:+.1f} cm anterior to the L4 body centre",
        f"  thesis (Schmid et al. model): {100 * ub['thesis_com_anterior_of_L4_m']:.1f} cm anterior to L4 -> "
        + ("agrees (within 1 cm)" if ub["agrees_with_thesis"] else "does NOT agree: MyoTorso has no arms and a posterior lumped upper body"),
    ]
    return "\n".join(lines)
