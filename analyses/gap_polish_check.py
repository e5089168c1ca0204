"""Check of the gap search's final polish on a published benchmark run: regenerate a case's data, then the
remainder test at the truth, at the run's final model, and at that model refitted along every gain direction
with its effects (rounds of ITERS secant steps while a round lowers the training chi2 by more than 10).

    python analyses/gap_polish_check.py CASE RUN_FOLDER [ITERS]   # e.g. docs/gap_benchmark/default_passenger
Prints one JSON line (results of 2026-12-04 in docs/gap_benchmark/polish_check/results.jsonl, one round each
except slow_activation_scale4)."""
import json, sys, time
import numpy as np
from trunk_drake.gap.benchmark import truth_configuration, select_cases, truth_options, _lag_kinematics
from trunk_drake.gap.synthetic import clean_trials, add_noise
from trunk_drake.gap.trials import prepare_trials, half
from trunk_drake.gap.refit import TimeDomainFitter, simulate_outputs
from trunk_drake.gap.space import SearchSpace
from trunk_drake.gap.measures import remainder, segment_chi2
from trunk_drake.gap.catalogue import effect
from trunk_drake.io.trials import OUTPUT_NAMES
from trunk_drake.parallel import WorkerPool

name, folder = sys.argv[1], sys.argv[2]
iters = int(sys.argv[3]) if len(sys.argv) > 3 else 3
t0 = time.perf_counter()
model, nominal = truth_configuration()
case = select_cases([name])[0]
designs = [("1hz_a", 1.0, case.seed), ("1hz_b", 1.0, case.seed + 1000), ("3hz", 3.0, case.seed + 2000)]
truth = truth_options(nominal, case)
clean = clean_trials(model, truth, designs)
if case.kind == "outside" and case.effects[0][0] == "kinematics_lag":
    clean = _lag_kinematics(clean, case.effects[0][1]["lag_s"])
data = prepare_trials(add_noise(clean, 0.1 * np.pi / 180, seed=case.seed), OUTPUT_NAMES)
noise = np.full(len(OUTPUT_NAMES), 0.1 * np.pi / 180)
d = json.load(open(f"{folder}/cases/{name}/diagnosis.json"))
final = d["final"]
space = SearchSpace.around(model, nominal)
nom_log = np.log10([space.layout.fixed[n.split('.',1)[0]][n.split('.',1)[1]] for n in space.layout.names])
fin_log = np.log10([final["gains"][n.split('.',1)[0]][n.split('.',1)[1]] for n in space.layout.names])
effects = tuple(effect(n) for n in final["effects"])
xe = []
for e in effects:
    for p in e.parameters:
        v = final["effects"][e.name][p.name]
        xe.append(np.log10(v) if p.log10 else v)
x0 = np.concatenate([fin_log - nom_log, xe])
out = {"case": name}
def rem(outputs):
    r = remainder(data, outputs, noise, OUTPUT_NAMES)
    return {"is_noise": r["is_noise"], "chi2": {k: round(v, 4) for k, v in r["chi2_per_sample"].items()},
            "lb_p": r["ljung_box"]["p"], "lb_q": r["ljung_box"]["q"], "frf_p": r["frf"]["p"],
            "heldout": sum(segment_chi2(t.steady_outputs, o, noise, half(t, "test")) for t, o in zip(data, outputs))}
ys = [simulate_outputs(model, truth, t, OUTPUT_NAMES)[0] for t in data]
out["truth"] = rem(ys); print("truth", out["truth"], flush=True)
with WorkerPool(model, 2) as pool:
    fitter = TimeDomainFitter(pool, space, data, noise, OUTPUT_NAMES)
    f0 = fitter.fit(effects, x0, [], space=space)
    out["final"] = rem(f0.outputs); print("final", out["final"], flush=True)
    f1 = fitter.fit(effects, x0, np.arange(x0.size), max_iterations=iters, space=space)
    rounds = [f1.train_chi2]
    while len(rounds) < 4:
        f2 = fitter.fit(effects, f1.x, np.arange(x0.size), max_iterations=iters, space=space)
        print("round", len(rounds) + 1, f2.train_chi2, f2.heldout_chi2, f2.values, flush=True)
        if f2.outputs is None or f1.train_chi2 - f2.train_chi2 <= 10: break
        f1 = f2; rounds.append(f1.train_chi2)
    out["polished"] = rem(f1.outputs); out["polished_values"] = f1.values; out["train"] = [f0.train_chi2, f1.train_chi2]
    print("polished", out["polished"], f1.values, f0.train_chi2, f1.train_chi2, flush=True)
out["sims"] = fitter.simulations; out["wall_s"] = time.perf_counter() - t0
print(json.dumps(out, default=float))
