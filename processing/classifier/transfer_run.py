"""Running a transfer study (`run_transfer`, what `rtchannel transfer` runs): the data, the pretrainings, the
worker processes, resuming, the report.

Files in the output folder: ``study.json`` (settings and data fingerprints; a resumed study must match),
``pretrained_s<seed>.pt`` (the simulation-only networks, checkpoints as `rtchannel train` writes),
``runs.jsonl`` (one line per finished training and its test; appended as they finish), and the report
(`transfer_report.write_report`: transfer.csv, transfer.md, transfer.png, transfer.json).
"""
from __future__ import annotations

import hashlib
import json
import os
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from processing.classifier.transfer import Arrays, Task, TransferConfig, plan_tasks, run_task, sim_only_rows
from processing.errors import InputError


@dataclass
class TransferStudy:
    """A finished (or resumed and finished) study.

    Attributes:
        config: its settings.
        rows: one dict per run (arm, shots, fold, seed, accuracy, macro_f1, confusion, n_real, seconds, ...).
        pretrained: per seed: checkpoint path, simulated validation accuracy, epochs.
        out: the output folder.
        seconds: wall time of this call [s] (a resumed study counts only what it ran).
        files: the report files written.
    """

    config: TransferConfig
    rows: list[dict]
    pretrained: list[dict]
    out: Path
    seconds: float
    files: list[Path] = field(default_factory=list)

    def summary(self) -> list[dict]:
        """Accuracy per arm and shot count over folds and seeds (`transfer_report.summarise`)."""
        from processing.classifier.transfer_report import summarise

        return summarise(self.rows)

    def worth(self) -> dict:
        """What the simulation is worth in real recordings per class (`transfer_report.simulation_worth`)."""
        from processing.classifier.transfer_report import simulation_worth

        return simulation_worth(self.summary())

    def __repr__(self) -> str:
        return (f"<TransferStudy {self.out}: {len(self.rows)} runs, {len(self.pretrained)} pretrained networks, "
                f"{self.seconds:.0f} s; {self.worth()['text']}>")


def _digest(parts) -> str:
    h = hashlib.sha256()
    for p in parts:
        h.update(str(p).encode() + b"\n")
    return h.hexdigest()[:16]


def load_study_data(sim, images, cfg: TransferConfig, labels=None, pretrained=None, progress: bool = False) -> dict:
    """The arrays and settings every task needs: simulated and real inputs preprocessed alike (the pretrained
    checkpoints' preprocessing when given, else ``cfg.preprocess``), the network settings and the folds.

    Args:
        sim: simulated dataset spec(s) (`load_dataset`).
        images: a folder of real labelled images, or an ``images:DIR[:FILTER]`` spec.
        cfg: the study settings.
        labels: labels CSV path or mapping for images whose names are not Glasgow names.
        pretrained: checkpoints to start from instead of pretraining, one per seed of ``cfg.seeds``.
        progress: progress bars while loading.
    """
    from processing.classifier.experiment import load_dataset
    from processing.classifier.model import ModelConfig
    from processing.classifier.real_data import image_arrays, is_image_spec
    from processing.classifier.splits import deployment_factors
    from processing.classifier.transfer import subject_folds
    from processing.labels import ACTIVITIES

    pre, mcfg, link, states = cfg.preprocess, None, cfg.link, {}
    if pretrained:
        from processing.classifier.checkpoint import load_checkpoint

        if len(pretrained) != len(cfg.seeds):
            raise InputError(f"give one pretrained checkpoint per seed ({len(cfg.seeds)}), got {len(pretrained)}")
        clfs = [load_checkpoint(p) for p in pretrained]
        first = clfs[0]
        if len(first.links) != 1 or any(c.preprocess != first.preprocess or c.model.cfg != first.model.cfg
                                        or list(c.links) != list(first.links) for c in clfs):
            raise InputError("pretrained checkpoints must be single-radar networks with one preprocessing and network")
        pre, mcfg, link = first.preprocess, first.model.cfg, first.links[0]
        states = {seed: c.model.state_dict() for seed, c in zip(cfg.seeds, clfs)}
    if mcfg is None:
        mcfg = cfg.model or ModelConfig(n_classes=len(ACTIVITIES), n_branches=1,
                                        input_size=(pre.n_velocity, pre.n_time))
    if isinstance(labels, (str, Path)):
        from processing.realdata.real_images import read_labels_csv

        labels = read_labels_csv(labels)
    ds = load_dataset(sim, [link], pre, progress=progress)
    spec = str(images) if is_image_spec(images) else f"images:{images}"
    x, y, groups, names, entries, left_out = image_arrays(spec, [link], pre, labels)
    if any(g.startswith("image:") for g in groups):
        raise InputError(f"{spec}: every real image needs its person (Glasgow names or a subject column in --labels): "
                         "the folds are grouped by person")
    deps = deployment_factors(ds.entries) if cfg.pretrain.val_split == "deployment" else None
    return {"config": cfg, "preprocess": pre, "model": mcfg, "link": link, "states": states,
            "sim": Arrays(ds.x, ds.y, ds.groups, ds.names), "deployments": deps,
            "real": Arrays(x, y, groups, names), "folds": subject_folds(groups, cfg.folds), "left_out": left_out,
            "fingerprint": {"sim": _digest(f"{e['item_id']}|{e.get('sha256')}" for e in ds.entries),
                            "real": _digest(e["image"]["sha256"] for e in entries), "n_sim": int(ds.y.size),
                            "n_real": int(y.size), "people": int(np.unique(groups).size)}}


def _append(path: Path, row: dict) -> None:
    """One JSON line, flushed and fsynced (a killed study loses at most the line being written)."""
    with open(path, "a") as f:
        f.write(json.dumps({k: v for k, v in row.items() if k != "state"}) + "\n")
        f.flush()
        os.fsync(f.fileno())


def _read_runs(path: Path) -> dict[str, dict]:
    runs = {}
    if path.is_file():
        for line in path.read_text().splitlines():
            try:
                row = json.loads(line)
            except json.JSONDecodeError:  # a line cut by a kill: that run is done again
                continue
            runs[row["key"]] = row
    return runs


def _save_pretrained(out: Path, seed: int, state: dict, data: dict, info: dict) -> Path:
    from processing.classifier.checkpoint import save_checkpoint
    from processing.classifier.model import build_model
    from processing.classifier.predictor import Classifier
    from processing.labels import ACTIVITIES

    net = build_model(data["model"])
    net.load_state_dict(state)
    clf = Classifier(model=net, preprocess=data["preprocess"], classes=list(ACTIVITIES), links=[data["link"]],
                     meta={"transfer_pretraining": {k: v for k, v in info.items() if k != "state"}})
    return save_checkpoint(out / f"pretrained_s{seed}.pt", clf)


def run_transfer(sim, images, out, config: TransferConfig | None = None, *, labels=None, pretrained=None,
                 workers: int = 2, progress: bool = True, log=print) -> TransferStudy:
    """Run (or resume) a transfer study and write its report.

    Args:
        sim: simulated dataset spec(s) for pretraining and the mixed arm.
        images: folder (or ``images:`` spec) of real labelled images of several people.
        out: output folder (created; a folder of an earlier run of the same study resumes it).
        config: the settings (default `TransferConfig()`).
        labels: labels CSV or mapping for images whose names are not Glasgow names.
        pretrained: checkpoints to use instead of pretraining, one per seed.
        workers: worker processes (1: everything in this process).
        progress: a progress bar.
        log: callable receiving one line per finished run (None: quiet).

    Returns:
        `TransferStudy` (its report already written into `out`).
    """
    cfg = TransferConfig() if config is None else config
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    data = load_study_data(sim, images, cfg, labels=labels, pretrained=pretrained, progress=progress)
    study = {"config": cfg.model_dump(mode="json"), "digest": cfg.digest(), "fingerprint": data["fingerprint"],
             "pretrained": [str(p) for p in pretrained or []]}
    if (out / "study.json").is_file():
        old = json.loads((out / "study.json").read_text())
        if {k: old.get(k) for k in study} != study:
            raise InputError(f"{out} holds a study with other settings or data; give another --out or remove it")
    else:
        from processing.atomic import write_text_atomic

        write_text_atomic(out / "study.json", json.dumps(study, indent=1) + "\n")
    runs_path = out / "runs.jsonl"
    done = _read_runs(runs_path)
    states = dict(data["states"])
    for seed in cfg.seeds:  # pretrained networks of an interrupted run
        ckpt = out / f"pretrained_s{seed}.pt"
        if seed not in states and ckpt.is_file():
            from processing.classifier.checkpoint import load_checkpoint

            states[seed] = load_checkpoint(ckpt).model.state_dict()
    pretrain_rows = [r for r in done.values() if r["arm"] == "pretrain"]
    todo_pre = [Task("pretrain", 0, -1, s) for s in cfg.seeds if s not in states]
    tasks = [t for t in plan_tasks(cfg) if t.key not in done]
    total = len(todo_pre) + len(tasks)
    if log:
        log(f"transfer study: {data['fingerprint']['n_real']} real images of {data['fingerprint']['people']} people "
            f"in {cfg.folds} folds, {data['fingerprint']['n_sim']} simulated items; {total} trainings to run "
            f"({len(done)} done before), {workers} worker(s)")
    rows = [r for r in done.values() if r["arm"] != "pretrain"]

    def finished(task: Task, row: dict) -> list[Task]:
        """Record a finished task; returns the tasks it made ready."""
        if task.arm == "pretrain":
            states[task.seed] = row["state"]
            _save_pretrained(out, task.seed, row["state"], data, row)
            pretrain_rows.append({k: v for k, v in row.items() if k != "state"})
            _append(runs_path, row)
        else:
            rows.append(row)
            _append(runs_path, row)
        if log:
            what = (f"pretrained seed {task.seed}: simulated validation {100 * row['val_accuracy']:.1f} %"
                    if task.arm == "pretrain" else f"{task.arm} {task.shots}/class fold {task.fold} seed {task.seed}: "
                    f"{100 * row['accuracy']:.1f} %")
            (bar.write if bar is not None else log)(f"{what} ({row['seconds']:.0f} s)")
        return [t for t in waiting if task.arm == "pretrain" and t.seed == task.seed]

    from tqdm import tqdm

    bar = tqdm(total=total, desc="transfer", unit="training", disable=not progress) if progress else None
    waiting = [t for t in tasks if t.arm != "real" and t.seed not in states]
    ready = todo_pre + [t for t in tasks if t not in waiting]
    if workers <= 1:
        while ready:
            task = ready.pop(0)
            new = finished(task, run_task(task, states.get(task.seed), data))
            waiting = [t for t in waiting if t not in new]
            ready += new
            if bar is not None:
                bar.update()
    else:
        _run_pool(ready, waiting, states, data, workers, finished, bar)
    if bar is not None:
        bar.close()
    missing = [s for s in cfg.seeds if s not in states]
    if missing:
        raise InputError(f"no pretrained network for seed(s) {missing}")
    have = {r["key"] for r in rows}
    rows += [r for r in sim_only_rows({s: states[s] for s in cfg.seeds}, data) if r["key"] not in have]
    from processing.classifier.transfer_report import write_report

    seconds = time.perf_counter() - t0
    pre_info = [{"seed": r["seed"], "path": str(out / f"pretrained_s{r['seed']}.pt"),
                 "val_accuracy": r.get("val_accuracy"), "epochs": r.get("epochs")} for r in pretrain_rows]
    meta = {"config": study["config"], "fingerprint": data["fingerprint"], "pretrained": pre_info,
            "seconds_this_run": seconds, "workers": workers, "left_out": data["left_out"],
            "run_seconds_total": float(sum(r.get("seconds", 0.0) for r in rows + pretrain_rows))}
    files = write_report(out, rows, meta, title=f"transfer: {Path(str(images)).name} with {Path(str(sim)).name}")
    return TransferStudy(config=cfg, rows=rows, pretrained=pre_info, out=out, seconds=seconds, files=files)


def _run_pool(ready, waiting, states, data, workers, finished, bar) -> None:
    """Run the tasks on `workers` spawned processes (one torch thread each), submitting a seed's pretrained-arm
    tasks when its pretraining finishes."""
    import multiprocessing
    from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

    from processing.classifier.transfer import _init_worker

    shipped = {k: v for k, v in data.items() if k != "states"}
    with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                             initializer=_init_worker, initargs=(shipped,)) as pool:
        running = {pool.submit(run_task, t, states.get(t.seed)): t for t in ready}
        while running:
            done, _ = wait(running, return_when=FIRST_COMPLETED)
            for fut in done:
                task = running.pop(fut)
                new = finished(task, fut.result())
                for t in new:
                    waiting.remove(t)
                    running[pool.submit(run_task, t, states[t.seed])] = t
                if bar is not None:
                    bar.update()


__all__ = ["TransferStudy", "load_study_data", "run_transfer"]
