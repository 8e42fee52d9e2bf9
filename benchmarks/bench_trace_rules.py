"""Benchmark (issue 26): the adaptive trace-rate rules against the 10 fps default, per activity, seed radar.

The distance rule (`trace_step_m`) and the aspect rule (`trace_step_deg`) at 1 s and 0.25 s largest gaps
(`trace_max_gap_s`), 5 fps for scale; error = p(v,t) EMD against the converged reference (mean of 3 seeds)
on the calibration motions (generator seed 0), 3 diffuse-phase seeds each; cost = wall time per simulated
second, round robin (`rtchannel.analysis.calibrate.calibrate`). ~10 min idle.

Run: .venv/bin/python benchmarks/bench_trace_rules.py
"""
from rtchannel.analysis.calibrate import calibrate
from rtchannel.analysis.speed_error import Setting
from rtchannel.radar import RadarConfig

CANDIDATES = [
    (Setting("defaults (10 fps)", "facets", {}), "default"),
    (Setting("5 fps", "facets", {"trace_fps": 5.0}), "candidate"),
    (Setting("distance 0.25 m", "facets", {"trace_step_m": 0.25}), "candidate"),
    (Setting("distance 0.25 m, gap 0.25 s", "facets", {"trace_step_m": 0.25, "trace_max_gap_s": 0.25}), "candidate"),
    (Setting("aspect 3 deg", "facets", {"trace_step_deg": 3.0}), "candidate"),
    (Setting("aspect 5 deg", "facets", {"trace_step_deg": 5.0}), "candidate"),
    (Setting("aspect 5 deg, gap 0.25 s", "facets", {"trace_step_deg": 5.0, "trace_max_gap_s": 0.25}), "candidate"),
    (Setting("aspect 10 deg, gap 0.25 s", "facets", {"trace_step_deg": 10.0, "trace_max_gap_s": 0.25}),
     "candidate"),
]

if __name__ == "__main__":
    table = calibrate(RadarConfig(), "seed radar", ("fall", "walk", "stand", "sit", "pick"), CANDIDATES, seeds=3,
                      reference_seeds=3)
    for r in table.rows:
        print(f"{r.label:32s} {r.s_per_sim_s:.3f} s/s  " + "  ".join(
            f"{a} {r.emd_m_s[a]:.3f}+-{r.emd_sem_m_s[a]:.3f}" for a in r.emd_m_s))
