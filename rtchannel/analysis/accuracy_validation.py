"""Validation of the accuracy budget (`rtchannel bench --validate-accuracy`): on motions the calibration did
not use, does each budget's choice stay within its target, and how much faster than the default is it?

Per motion: the converged reference (as the calibration's), then the default setting and every budget
(`simulate(..., accuracy=...)`) at `seeds` diffuse-phase seeds; the achieved error is the mean p(v,t) EMD
over links and seeds, the cost the wall time per simulated second. An EMD budget is absolute: a case is
within it when the achieved error is at most that many m/s. The named budgets are relative to the default
setting, and an absolute EMD calibrated on one motion does not carry over to another (a slow walk's default
error is not a fast walk's), so they are checked against the default's achieved error on the same motion:
``balanced`` within when no worse than the default, ``fast`` within `FAST_FACTOR` times it, each up to
twice the standard error of the difference over the seeds (one run's speckle is as large as the
differences between settings). ``exact`` has no target.

Held-out motions: the procedural generator at seed 1 (other amplitudes and timing; the fall goes to the
left where the calibration's fell forward), walks at 0.6 and 1.4 m/s, and, where the data is present, real
takes (a Daz CMU walk, CMU 75_17's sit-down, an OpenCap stand-up, an HDM05 pick).
"""
from __future__ import annotations

import csv
import io
import time
from typing import Any

import numpy as np

from processing.atomic import savefig_atomic, write_text_atomic
from processing.labels import ACTIVITIES
from rtchannel.accuracy import FAST_FACTOR, parse_budget, target
from rtchannel.analysis.speed_error import QUICK_REFERENCE, _mean_distances, converged_reference

# real takes (data registry path, activity, load/trim options); skipped when the data is not present
REAL_TAKES: tuple[tuple[str, str, dict[str, Any]], ...] = (
    ("mocap/cmu/walk_daz", "walk", {}),
    ("mocap/cmu/sit/75_17.bvh", "sit", {"trim": (0.0, 1.5)}),
    ("mocap/opencap/sit_stand/opencap_STS_sample_mocap.json", "stand", {"trim": (2.8, 4.2)}),
    ("mocap/hdm05/pick", "pick", {"skeleton": "mocap/hdm05/asf"}),
)


def held_out_motions(activities=ACTIVITIES, real: bool = True, seeds=(1,)) -> list[tuple[str, object]]:
    """(name, Motion) pairs the calibration (generator seed 0) did not see: the generator at `seeds` (walks:
    one at 0.6 m/s and one at 1.4 m/s) and the real takes (module doc)."""
    from rtchannel.motion.procedural import generate

    out: list[tuple[str, object]] = []
    for act in activities:
        if act == "walk":
            for seed, speed in ((1, 0.6), (2, 1.4)):
                m = generate("walk", seed=seed, speed=speed, duration=2.5 if speed > 1 else 3.0, start=(-1.8, 0.0))
                out.append((f"walk {speed} m/s (seed {seed})", m))
            continue
        for seed in seeds:
            out.append((f"{act} (seed {seed})", generate(act, seed=seed)))
    if real:
        out += [t for t in (_real_take(*spec) for spec in REAL_TAKES if spec[1] in activities) if t is not None]
    return out


def _real_take(relpath: str, activity: str, opts: dict):
    """(name, Motion) of a registered take, or None when it is not available locally (no download)."""
    from rtchannel.data_registry import fetch, fetch_folder
    from rtchannel.motion.compose import place_take
    from rtchannel.motion.pose import Motion

    try:
        if "." in relpath.rsplit("/", 1)[-1]:
            path = fetch(relpath, download=False)
        else:
            path = sorted(p for p in fetch_folder(relpath, download=False).iterdir() if p.is_file())[0]
        load: dict[str, Any] = {"activity": activity}
        if "skeleton" in opts:  # the actor's ASF: the longest name that starts the AMC's (HDM05 naming)
            asfs = fetch_folder(opts["skeleton"], download=False).glob("*.asf")
            load["skeleton"] = max((a for a in asfs if path.stem.startswith(a.stem)), key=lambda a: len(a.stem))
        motion = Motion.from_file(path, **load)
    except Exception:  # noqa: BLE001 - data absent (a clone without ../shared): validate on the rest
        return None
    motion = place_take(motion, start=(-1.8, 0.0) if activity == "walk" else None, trim=opts.get("trim"))
    return f"{activity}: {path.name} (real take)", motion


def validate(radar, table, motions, budgets=("fast", "balanced", "exact"), seeds: int = 2,
             reference_seeds: int = 4, calibration=None, progress=None, reference=QUICK_REFERENCE) -> list[dict]:
    """One row per (motion, budget) and one per motion for the default setting: achieved EMD [m/s] against
    the converged reference, target [m/s], chosen setting, wall time per simulated second [s], speed-up
    against the default on the same motion and whether the case is within budget."""
    from rtchannel.pipeline import simulate

    rows = []
    for name, motion in motions:
        _, ref, _ = converged_reference(reference, motion, radar, reference_seeds)
        runs = {}
        for budget in ("default", *budgets):
            emd, wall, record = [], 0.0, {}
            for s in range(seeds):
                t0 = time.perf_counter()
                kw = {} if budget == "default" else {"accuracy": budget, "calibration": calibration or table}
                res = simulate(motion, radar, backend="facets", seed=200 + s, **kw)
                wall += time.perf_counter() - t0
                emd.append(_mean_distances({k: r.signature for k, r in res.links.items()}, ref)["emd_m_s"])
                record = res.config.get("accuracy", {})
            runs[budget] = (np.array(emd), wall / (seeds * motion.duration), record)
            if progress:
                progress(1)
        base_emd, base_cost, _ = runs["default"]
        for budget, (achieved, cost, record) in runs.items():
            limit, allowance = None, 0.0
            if budget in ("balanced", "fast"):
                factor = 1.0 if budget == "balanced" else FAST_FACTOR
                limit = factor * float(base_emd.mean())
                allowance = 2.0 * _sem_of_difference(achieved, factor * base_emd)
            elif budget not in ("default", "exact"):
                limit = target(parse_budget(budget), table, motion.activity)
            rows.append({"motion": name, "activity": motion.activity, "budget": str(budget),
                         "chosen": record.get("chosen", "facets defaults"), "target_emd_m_s": limit,
                         "allowance_m_s": allowance, "achieved_emd_m_s": float(achieved.mean()), "s_per_sim_s": cost,
                         "speedup": base_cost / cost,
                         "within": None if limit is None else bool(achieved.mean() <= limit + allowance)})
    return rows


def _sem_of_difference(a: np.ndarray, b: np.ndarray) -> float:
    """Standard error [m/s] of mean(a) - mean(b) from the per-seed values (0 with one seed)."""
    if len(a) < 2 or len(b) < 2:
        return 0.0
    return float(np.sqrt(a.var(ddof=1) / len(a) + b.var(ddof=1) / len(b)))


def summary(rows: list[dict]) -> dict[str, dict]:
    """Per budget: cases, share within budget, median speed-up, mean achieved EMD [m/s]."""
    out = {}
    for budget in dict.fromkeys(r["budget"] for r in rows):
        mine = [r for r in rows if r["budget"] == budget]
        judged = [r["within"] for r in mine if r["within"] is not None]
        out[budget] = {"cases": len(mine), "within_share": float(np.mean(judged)) if judged else None,
                       "median_speedup": float(np.median([r["speedup"] for r in mine])),
                       "mean_emd_m_s": float(np.mean([r["achieved_emd_m_s"] for r in mine]))}
    return out


def write_validation(rows: list[dict], out_dir, meta: dict) -> list:
    """accuracy_validation.csv / .md (per case and per budget) / .png (achieved error against cost)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out_dir.mkdir(parents=True, exist_ok=True)
    keys = ["motion", "activity", "budget", "chosen", "target_emd_m_s", "allowance_m_s", "achieved_emd_m_s",
            "s_per_sim_s", "speedup", "within"]
    buf = io.StringIO(newline="")
    w = csv.writer(buf)
    w.writerow(keys)
    for r in rows:
        w.writerow([f"{r[k]:.4g}" if isinstance(r[k], float) else r[k] for k in keys])
    p_csv = out_dir / "accuracy_validation.csv"
    write_text_atomic(p_csv, buf.getvalue())
    summ = summary(rows)
    md = [f"Accuracy budget on held-out motions: {meta.get('radar', '')}; reference {QUICK_REFERENCE.label}, mean of "
          f"{meta.get('reference_seeds')} seeds; each setting at {meta.get('seeds')} seeds.", "",
          "| budget | cases | within budget | median speed-up vs default | mean EMD [m/s] |", "|---|---|---|---|---|"]
    for b, s in summ.items():
        share = "n/a" if s["within_share"] is None else f"{100 * s['within_share']:.0f} %"
        md.append(f"| {b} | {s['cases']} | {share} | {s['median_speedup']:.2f}x | {s['mean_emd_m_s']:.3f} |")
    md += ["", "| motion | budget | chosen | target [m/s] | achieved [m/s] | s per sim. s | speed-up | within |",
           "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        tgt = "-" if r["target_emd_m_s"] is None else f"{r['target_emd_m_s']:.3f}"
        if r["allowance_m_s"]:
            tgt += f" (+{r['allowance_m_s']:.3f})"
        ok = "-" if r["within"] is None else ("yes" if r["within"] else "**no**")
        md.append(f"| {r['motion']} | {r['budget']} | {r['chosen']} | {tgt} | {r['achieved_emd_m_s']:.3f} | "
                  f"{r['s_per_sim_s']:.3g} | {r['speedup']:.2f}x | {ok} |")
    p_md = out_dir / "accuracy_validation.md"
    write_text_atomic(p_md, "\n".join(md) + "\n")
    fig, ax = plt.subplots(figsize=(9, 5.5))
    colours = {"default": "k", "exact": "tab:purple", "balanced": "tab:blue", "fast": "tab:orange"}
    for b in dict.fromkeys(r["budget"] for r in rows):
        mine = [r for r in rows if r["budget"] == b]
        ax.scatter([r["s_per_sim_s"] for r in mine], [r["achieved_emd_m_s"] for r in mine], s=22,
                   color=colours.get(b, "tab:green"), label=f"{b} ({summ[b]['median_speedup']:.2f}x)")
        for r in mine:
            if r["within"] is False:
                ax.scatter(r["s_per_sim_s"], r["achieved_emd_m_s"], s=90, facecolors="none", edgecolors="red")
    ax.scatter([], [], s=90, facecolors="none", edgecolors="red", label="over its target")
    ax.set_xscale("log")
    ax.set_xlabel("wall time per simulated second [s]")
    ax.set_ylabel("p(v,t) EMD to converged reference [m/s]")
    ax.set_title(f"accuracy budget on held-out motions: {meta.get('radar', '')}", fontsize=10)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    fig.tight_layout()
    p_png = out_dir / "accuracy_validation.png"
    savefig_atomic(fig, p_png, dpi=120)
    plt.close(fig)
    return [p_csv, p_md, p_png]
