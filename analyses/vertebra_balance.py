"""Why static optimisation at rest saturates muscles and why exact-balance flexion strength is tiny:
each vertebra's own balance (trunk_drake.optim.static.vertebra_balances), and what the rhythm and a
tolerated deflection change. Prints JSON: ``python analyses/vertebra_balance.py``."""

import numpy as np

import trunk_drake as td
from trunk_drake.commands import print_json
from trunk_drake.optim.static import StaticOptimizer, vertebra_balances
from trunk_drake.optim.strength import StrengthProblem, load_case

REST_CASES = {  # name: (configuration, StaticOptimizer options): static optimisation at rest, gravity only
    "sagittal, activations >= 0.01 (default)": ("sagittal", {}),
    "sagittal, activations >= 0": ("sagittal", {"min_activation": 0.0}),
    "sagittal, 2 deg deflection": ("sagittal", {"deflection_tolerance": np.radians(2.0)}),
    "rhythm, activations >= 0.01": ("rhythm", {}),
}


def _frame(result, model) -> dict:
    order = np.argsort(-result.activations)[:6]
    return {"cost_sum_a2": result.cost, "max_activation": float(result.activations.max()),
            "at_upper_bound": result.at_upper_bound, "highest": {model.muscles[i]: float(result.activations[i]) for i in order},
            "bushing_moments_Nm": result.deflection_moments.tolist()}


def rest() -> dict:
    out, models = {}, {}
    for name, (dofs, options) in REST_CASES.items():
        model = models.setdefault(dofs, td.load_model(dofs))
        optimizer = StaticOptimizer(model, **options)
        balance = optimizer.balance(np.zeros(len(model.coordinates)))
        out[name] = {"required_Nm": dict(zip(balance.coordinates, balance.required.tolist())),
                     **_frame(optimizer.solve_balance(balance), model)}
        if dofs == "sagittal" and not options:
            out[name]["vertebrae"] = vertebra_balances(balance, optimizer.min_activation, 1.0)
    return out


def flexion() -> dict:
    model = td.load_model("spine3d")
    out = {}
    for floor in (0.0, 0.01):
        problem = StrengthProblem(StaticOptimizer(model, min_activation=floor), load_case(model, "flexion"))
        force, sensitivity = problem.maximum()
        out[f"activations >= {floor:g}"] = {
            "max_force_N": force, "sensitivity_N_per_Nm": {c: float(v) for c, v in zip(problem.coordinates, sensitivity) if abs(v) > 0.5},
            "vertebrae": vertebra_balances(problem.balance, floor, 1.0, problem.per_newton)}
    return out


if __name__ == "__main__":
    print_json({"rest": rest(), "flexion_strength_independent_levels": flexion()})
