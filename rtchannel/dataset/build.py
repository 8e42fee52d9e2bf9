"""Building a dataset from Python: a plan (file, preset name or `Plan`) run into a resumable dataset folder; and
reading the plan files of the dataset-level commands (cross-validation plans) with the plans' bounded reader.

`rtchannel dataset --config PLAN --out DIR` is argument parsing and printing around `build_dataset`; both
go through `load_plan` (validation, one-line errors) and `run_plan` (Dask, shards, index, resume).
"""
from __future__ import annotations

from pathlib import Path

from processing.errors import InputError
from rtchannel.dataset.plan import Plan, WorkItem, expand, load_plan
from rtchannel.dataset.runner import RunSummary, run_plan


def plan_dataset(plan: str | Path | Plan, *, backend: str | None = None,
                 fetch: bool = True) -> tuple[Plan, list[WorkItem]]:
    """(validated plan, its work items) without running anything (what ``--dry-run`` counts).

    Args:
        plan: a plan YAML/JSON file, a preset name ("seed", "glasgow", ...) or a `Plan`.
        backend: replaces the plan's backend ("points", "facets", "sionna"), checked with its options.
        fetch: download third-party motion files the plan names (False: count them from the registry).
    """
    if isinstance(plan, Plan):
        if backend is not None:
            plan = Plan.model_validate({**plan.model_dump(), "backend": backend})
    else:
        plan = load_plan(plan, backend=backend)
    return plan, expand(plan, fetch=fetch)


def build_dataset(plan: str | Path | Plan, out: str | Path, *, backend: str | None = None,
                  scheduler: str | None = None, workers: int | None = None, retries: int = 2,
                  progress: bool = False) -> RunSummary:
    """Run every unfinished item of `plan` into the dataset folder `out` (HDF5 shards, index.jsonl,
    errors.jsonl, plan.json); running it again resumes without duplicates or gaps.

    Args:
        plan: a plan YAML/JSON file, a preset name ("seed", "glasgow", ...) or a `Plan`.
        out: the dataset folder (created; must hold this plan's dataset or nothing).
        backend: replaces the plan's backend.
        scheduler: address of a running Dask scheduler; default a local cluster of `workers` processes.
        workers: local worker processes (default: the number of cores; 1 runs in this process).
        retries: extra attempts for a failing item.
        progress: show a progress bar.

    Returns:
        `RunSummary` (items done before and now, failures, seconds, workers; ``complete``).
    """
    if not isinstance(plan, Plan) or backend is not None:  # a given Plan was validated (and expanded) by its maker
        plan, _ = plan_dataset(plan, backend=backend)  # a bad plan fails here, before `out` is created
    return run_plan(plan, out, scheduler=scheduler, workers=workers, retries=retries, progress=progress)




def read_crossval_plan(path: str | Path) -> list[dict]:
    """The experiments of a cross-validation plan file (YAML: ``experiments: [{name, train: SPEC, test: [SPEC,
    ...]}]``), read with the bounded YAML reader of plans (`rtchannel.safe_yaml`: size and alias bounds, errors
    naming the line, never quoting the file).

    Args:
        path: the YAML file.

    Returns:
        [{"name", "train", "test": [spec, ...]}] (`processing.classifier.experiment.crossval_experiments`).
    """
    from processing.classifier.experiment import crossval_experiments
    from rtchannel.safe_yaml import read_yaml_mapping

    path = Path(path)
    if not path.is_file():
        raise InputError(f"crossval plan not found: {path}")
    return crossval_experiments(read_yaml_mapping(path, "crossval plan"), str(path))


__all__ = ["build_dataset", "plan_dataset", "read_crossval_plan"]
