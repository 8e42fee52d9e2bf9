"""Calibration of the accuracy budget (`rtchannel bench --calibrate`): speed and error of candidate settings
of the facets backend, per activity, for one radar; the table `rtchannel.accuracy` chooses from.

For each activity a procedural motion (seed 0) is simulated with the converged reference (facets on the full
mesh, every frame traced, every path kept, the mean of `reference_seeds` diffuse-phase seeds, as
`speed_error.converged_reference`) and with every candidate at `seeds` diffuse-phase seeds; a candidate's
error is its mean p(v,t) EMD over links and seeds, its cost the wall time per simulated second over all
activities. Averaging the candidates over seeds matters: one run sits a speckle distance from the
expected signature (`single_run_floor_m_s`) that is as large as the differences between settings, so a
single-seed ranking would be decided by the speckle draw.

Candidates combine the speed knobs (LOD, trace rate, gain cut, clutter) with the scene-dependent rules of
`rtchannel.backends.scene_model` (``lod="auto"``, ``walls="auto"``, ``trace_step_m``).
"""
from __future__ import annotations

import statistics
import time
from dataclasses import replace

import numpy as np

from processing.labels import ACTIVITIES
from rtchannel.accuracy import CalibrationRow, CalibrationTable
from rtchannel.analysis.speed_error import QUICK_REFERENCE, Setting, _mean_distances, converged_reference

EXACT = {"lod": "full", "trace_fps": None, "image_lod": None, "min_relative_gain_db": None}
CANDIDATES: tuple[tuple[Setting, str], ...] = (
    (Setting("facets defaults (10k, images 2k, 10 fps)", "facets", {}), "default"),
    (Setting("facets exact (full LOD, every frame, every path)", "facets", dict(EXACT)), "exact"),
    (Setting("facets 10k, images 5k", "facets", {"image_lod": "5k"}), "candidate"),
    (Setting("facets LOD auto, images on it", "facets", {"lod": "auto", "image_lod": None}), "candidate"),
    (Setting("facets 10k, images 2k, 5 fps", "facets", {"trace_fps": 5.0}), "candidate"),
    (Setting("facets 5k, images 5k", "facets", {"lod": "5k", "image_lod": None}), "candidate"),
    (Setting("facets 2k, images 2k", "facets", {"lod": "2k", "image_lod": None}), "candidate"),
    (Setting("facets walls auto (-15 dB)", "facets", {"walls": "auto", "wall_cut_db": -15.0}), "candidate"),
    (Setting("facets walls auto (-15 dB), 5k, images 5k", "facets",
             {"walls": "auto", "wall_cut_db": -15.0, "lod": "5k", "image_lod": None}), "candidate"),
    (Setting("facets trace step 0.25 m", "facets", {"trace_step_m": 0.25}), "candidate"),
    (Setting("facets walls auto (-15 dB), trace step 0.25 m", "facets",
             {"walls": "auto", "wall_cut_db": -15.0, "trace_step_m": 0.25}), "candidate"),
    (Setting("facets 10k, images 5k, trace step 0.25 m", "facets", {"image_lod": "5k", "trace_step_m": 0.25}),
     "candidate"),
    (Setting("facets no clutter", "facets", {"clutter": False}), "candidate"),
    # measured, never chosen (`rtchannel.accuracy`): the gain cut's effect changes sign between motions
    (Setting("facets gain cut -40 dB", "facets", {"min_relative_gain_db": -40.0}), "measured"),
    (Setting("facets gain cut -30 dB", "facets", {"min_relative_gain_db": -30.0}), "measured"),
    (Setting("facets 10k, images 5k, gain cut -30 dB", "facets", {"image_lod": "5k", "min_relative_gain_db": -30.0}),
     "measured"),
    (Setting("facets walls auto (-15 dB), gain cut -30 dB", "facets",
             {"walls": "auto", "wall_cut_db": -15.0, "min_relative_gain_db": -30.0}), "measured"),
    (Setting("facets 2k, images 2k, gain cut -30 dB", "facets",
             {"lod": "2k", "image_lod": None, "min_relative_gain_db": -30.0}), "measured"),
    (Setting("points (21 scatterers)", "points", {}), "points"),
)


def calibration_motion(activity: str, seed: int = 0, duration_s: float = 3.0):
    """The procedural motion an activity is calibrated on: at the origin facing +x (toward the presets'
    radars), a walk of `duration_s` from (-2, 0) m at 1 m/s; 0.5 s pads."""
    from rtchannel.motion.procedural import generate

    if activity == "walk":
        return generate("walk", seed=seed, speed=1.0, duration=duration_s, start=(-2.0, 0.0))
    return generate(activity, seed=seed)


def _run(setting: Setting, motion, radar, seed: int) -> tuple[float, dict]:
    from rtchannel.pipeline import simulate

    t0 = time.perf_counter()
    opts = dict(setting.options) if setting.backend == "points" else {**setting.options, "seed": seed}
    res = simulate(motion, radar, backend=setting.backend, **opts)
    return time.perf_counter() - t0, {k: r.signature for k, r in res.links.items()}


def calibration_motions(activities=ACTIVITIES, motion_seeds=(0,)) -> dict:
    """{key: Motion} of every activity at every generator seed in `motion_seeds`: key = the activity for seed
    0, "activity (motion seed s)" otherwise. Each key is calibrated as an activity of its own, so a setting
    must meet a budget on every motion: one motion per activity let a -30 dB gain cut look better than the
    default on the calibration fall and fail on a held-out one (docs/results.md)."""
    return {(a if s == 0 else f"{a} (motion seed {s})"): calibration_motion(a, s) for s in motion_seeds
            for a in activities}


def merge_tables(base: CalibrationTable, more: CalibrationTable) -> CalibrationTable:
    """`base` with the errors of `more` (same rows, other motions) added: costs stay `base`'s (timed in one
    run, round robin), errors and floors of both. Raises ValueError when the rows or reference differ."""
    if [r.label for r in base.rows] != [r.label for r in more.rows] or base.reference != more.reference:
        raise ValueError("tables to merge must have the same rows and reference")
    rows = [r.model_copy(update={"emd_m_s": {**r.emd_m_s, **m.emd_m_s},
                                 "emd_sem_m_s": {**r.emd_sem_m_s, **m.emd_sem_m_s}})
            for r, m in zip(base.rows, more.rows)]
    return base.model_copy(update={"rows": rows, "motions": {**base.motions, **more.motions},
                                   "single_run_floor_m_s": {**base.single_run_floor_m_s, **more.single_run_floor_m_s}})


def calibrate(radar, radar_name: str, activities=ACTIVITIES, candidates=CANDIDATES, seeds: int = 2,
              reference_seeds: int = 4, motions: dict | None = None, progress=None,
              reference: Setting = QUICK_REFERENCE) -> CalibrationTable:
    """Measure every candidate on every activity (module doc) for `radar` and return the table.

    Args:
        radar: `rtchannel.RadarConfig`. radar_name: its name in the table.
        activities: activities to calibrate on. candidates: (Setting, role) pairs; exactly one "default"
            and one "exact" among them.
        seeds: diffuse-phase seeds per candidate. reference_seeds: seeds averaged into the reference.
        motions: {activity: Motion} to use instead of `calibration_motion` (`calibration_motions` for several
            per activity; `activities` are then its keys).
        progress: optional callable receiving 1 per finished run.
        reference: the converged reference's setting (default: facets full LOD, full accuracy).
    """
    motions = motions or {a: calibration_motion(a) for a in activities}
    emd: dict[str, dict[str, float]] = {s.label: {} for s, _ in candidates}
    sem: dict[str, dict[str, float]] = {s.label: {} for s, _ in candidates}
    wall = {s.label: 0.0 for s, _ in candidates}
    simulated = 0.0
    floors = {}
    warmed = set()
    for act in activities:
        motion = motions[act]
        _, ref, self_error = converged_reference(reference, motion, radar, reference_seeds)
        floors[act] = float(self_error.get("single_run_emd_m_s", float("nan")))
        if progress:
            progress(1)
        simulated += motion.duration * seeds
        for setting, _role in candidates:
            key = (setting.backend, repr(sorted(setting.options.items())))
            if key not in warmed:  # scene, LOD and kernel loading are not timed
                n = min(motion.n_frames, max(8, int(0.5 * motion.fps)))  # longer than any DSP window
                short = replace(motion, positions=motion.positions[:n], rotations=motion.rotations[:n])
                _run(setting, short, radar, 0)
                warmed.add(key)
        runs: dict[str, list[float]] = {s.label: [] for s, _ in candidates}
        for s in range(seeds):  # round robin: a change of machine load hits every candidate alike
            for setting, _role in candidates:
                t, sig = _run(setting, motion, radar, 100 + s)  # seeds apart from the reference's 1..n
                wall[setting.label] += t
                runs[setting.label].append(_mean_distances(sig, ref)["emd_m_s"])
                if progress and s == seeds - 1:
                    progress(1)
        for setting, _role in candidates:
            r = runs[setting.label]
            emd[setting.label][act] = float(np.mean(r))
            sem[setting.label][act] = float(np.std(r, ddof=1) / np.sqrt(len(r))) if len(r) > 1 else float("nan")
    rows = [CalibrationRow(label=s.label, backend=s.backend, options=dict(s.options),
                           s_per_sim_s=wall[s.label] / simulated, emd_m_s=emd[s.label], emd_sem_m_s=sem[s.label],
                           role=role) for s, role in candidates]
    wf = radar.waveform
    return CalibrationTable(radar=radar_name, carrier_hz=wf.carrier_hz, range_resolution_m=wf.range_resolution,
                            reference=f"{reference.label}, mean of {reference_seeds} seeds",
                            motions={a: _describe(motions[a]) for a in activities}, seeds=seeds,
                            single_run_floor_m_s=floors, rows=rows)


def _describe(motion) -> str:
    p = motion.params or {}
    keys = ("activity", "seed", "speed", "duration", "source", "file")
    return ", ".join(f"{k}={p[k]}" for k in keys if k in p) or motion.activity


def run_count(activities, candidates=CANDIDATES, seeds: int = 2) -> int:
    """Progress units of `calibrate` (one per reference and one per candidate and activity)."""
    return len(activities) * (1 + len(candidates))


def summary_rows(table: CalibrationTable) -> list[dict]:
    """Per row: label, cost, worst and mean EMD over activities, and the speed-up against the default."""
    base = table.row("default").s_per_sim_s
    out = []
    for r in table.rows:
        vals = list(r.emd_m_s.values())
        out.append({"label": r.label, "role": r.role, "s_per_sim_s": r.s_per_sim_s, "speedup": base / r.s_per_sim_s,
                    "emd_mean": statistics.fmean(vals), "emd_worst": max(vals),
                    **{f"emd_{a}": v for a, v in r.emd_m_s.items()}})
    return out


def write_calibration(table: CalibrationTable, out_dir) -> list:
    """calibration.json (the table `--calibration` takes), calibration.md (per row and activity) and
    calibration.png (worst-activity error against cost, the budgets' choices marked)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from processing.atomic import savefig_atomic, write_text_atomic
    from rtchannel.accuracy import choose

    out_dir.mkdir(parents=True, exist_ok=True)
    p_json = out_dir / "calibration.json"
    write_text_atomic(p_json, table.model_dump_json(indent=1) + "\n")
    acts = list(table.motions) or sorted({a for r in table.rows for a in r.emd_m_s})
    summ = summary_rows(table)
    picks: dict[str, str | None] = {}
    for budget in ("fast", "balanced", "exact"):
        try:
            picks[budget] = choose(budget, "facets", table)[0].label
        except ValueError:
            picks[budget] = None
    md = [f"Calibration for {table.radar} ({table.carrier_hz / 1e9:g} GHz, {table.range_resolution_m:.3f} m bins); "
          f"reference: {table.reference}; {table.seeds} seeds per setting.",
          "Single-run floor (EMD between two reference runs): "
          + ", ".join(f"{a} {v:.3f}" for a, v in table.single_run_floor_m_s.items()) + " m/s.",
          "Budgets over all activities (worst case): " + "; ".join(f"{b} -> {p}" for b, p in picks.items()), "",
          "| setting | s per simulated s | speed-up vs default | worst EMD | " + " | ".join(acts) + " |",
          "|---|---|---|---|" + "---|" * len(acts)]
    for s in summ:
        md.append(f"| {s['label']} | {s['s_per_sim_s']:.3g} | {s['speedup']:.2f}x | {s['emd_worst']:.3f} | "
                  + " | ".join(f"{s.get('emd_' + a, float('nan')):.3f}" for a in acts) + " |")
    p_md = out_dir / "calibration.md"
    write_text_atomic(p_md, "\n".join(md) + "\n")
    fig, axes = plt.subplots(1, 2, figsize=(15, 6.5), gridspec_kw={"width_ratios": [1, 1]})
    ax = axes[0]
    for i, (s, r) in enumerate(zip(summ, table.rows), start=1):  # numbered: the labels are in the heat map
        colour = {"default": "k", "exact": "tab:purple", "points": "tab:green",
                  "measured": "tab:gray"}.get(r.role, "tab:blue")
        ax.scatter(s["s_per_sim_s"], s["emd_worst"], color=colour, s=30, zorder=3)
        mark = [b for b, p in picks.items() if p == r.label]
        ax.annotate(f"{i}" + (f" ({', '.join(mark)})" if mark else ""), (s["s_per_sim_s"], s["emd_worst"]),
                    fontsize=8, xytext=(4, 3), textcoords="offset points")
    ax.axhline(table.row("default").error(None), color="k", lw=0.8, ls=":", label="default's worst-activity error")
    ax.set_xscale("log")
    ax.set_xlabel("wall time per simulated second [s]")
    ax.set_yscale("log")  # the points row sits an order of magnitude above the mesh settings
    ax.set_ylabel("worst-activity p(v,t) EMD [m/s]")
    ax.set_title(f"calibration: {table.radar}; budgets chosen over all activities", fontsize=10)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    ax = axes[1]
    grid = np.array([[r.emd_m_s.get(a, np.nan) for a in acts] for r in table.rows])
    im = ax.imshow(grid, cmap="viridis", aspect="auto")
    ax.set_xticks(range(len(acts)), [a.replace(" (motion seed ", "\nseed ").rstrip(")") for a in acts], fontsize=8)
    ax.set_yticks(range(len(table.rows)), [f"{i} {r.label[:48]}" for i, r in enumerate(table.rows, start=1)],
                  fontsize=7)
    for i in range(grid.shape[0]):
        for j in range(grid.shape[1]):
            ax.text(j, i, f"{grid[i, j]:.3f}", ha="center", va="center", fontsize=6, color="w")
    fig.colorbar(im, ax=ax, label="EMD [m/s]")
    ax.set_title("error per calibration motion", fontsize=10)
    fig.tight_layout()
    p_png = out_dir / "calibration.png"
    savefig_atomic(fig, p_png, dpi=110)
    plt.close(fig)
    return [p_json, p_md, p_png]
