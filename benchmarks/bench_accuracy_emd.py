"""Benchmark (issue 26): EMD of the bench walk (5 s toward Radar 1, seed radar) for the default and the budgets,
against the converged quick reference (facets full LOD, full accuracy, mean of N seeds); settings at 5 diffuse seeds.
Run: .venv/bin/python benchmarks/bench_accuracy_emd.py [N] [--cuts]  (N reference seeds, default 6; ~6 min idle;
--cuts adds the gain-cut settings -40 and -30 dB)"""
import json
import sys
import numpy as np
from rtchannel.analysis.chain_bench import exact_duration_walk
from rtchannel.analysis.speed_error import QUICK_REFERENCE, _mean_distances, converged_reference
from rtchannel.pipeline import simulate
from rtchannel.radar import RadarConfig
m, r = exact_duration_walk(5.0), RadarConfig()
n_seeds = int(sys.argv[1]) if len(sys.argv) > 1 and sys.argv[1].isdigit() else 6
_, ref, self_err = converged_reference(QUICK_REFERENCE, m, r, n_seeds)
out = {"reference_self_emd": self_err["emd_m_s"], "single_run_floor": self_err["single_run_emd_m_s"]}
settings = [("default", {}), ("balanced", {"accuracy": "balanced"}), ("fast", {"accuracy": "fast"})]
if "--cuts" in sys.argv:
    settings += [("gain cut -40 dB", {"min_relative_gain_db": -40.0}),
                 ("gain cut -30 dB", {"min_relative_gain_db": -30.0})]
for name, kw in settings:
    e = []
    for s in range(100, 105):
        res = simulate(m, r, backend="facets", seed=s, **kw)
        e.append(_mean_distances({k: x.signature for k, x in res.links.items()}, ref)["emd_m_s"])
    out[name] = {"emd_mean": float(np.mean(e)), "emd_sem": float(np.std(e, ddof=1) / np.sqrt(len(e))), "runs": e,
                 "chosen": res.config.get("accuracy", {}).get("chosen", "defaults")}
print(json.dumps(out, indent=1))
