"""Run a plan's work items with Dask (or in this process for one worker), resumably, into HDF5 shards.

* Items are processed in batches of `items_per_shard` (mesh backends: all items of one motion, which share
  one backend run); each batch is one Dask task that writes one shard
  (temporary file, fsync, rename) and returns the entries. The shards are the source of truth: on start
  the runner removes orphan temporary files, re-reads every shard and checks every stored array against
  its sha256 (`scan_shards(verify=True, repair=True)`): a shard that is unreadable, foreign or holds a
  failing item is renamed ``*.bad`` (never deleted) and its verified items are kept in a new shard of the
  same name. It then rebuilds the index from the shards and skips every item already in one, so a killed
  run resumes without duplicates or gaps and corrupted data is computed again, never passed on.
* An item that raises is retried `retries` times inside its task; if it keeps failing it is recorded in
  DIR/errors.jsonl with its error and the rest of the run goes on. A task whose worker dies is retried
  by Dask, then split into single-item tasks so one bad item cannot sink its batch.
* Threads: every worker runs one task at a time with BLAS/OpenMP limited to one thread (Dask's nanny
  sets OMP/MKL/OPENBLAS_NUM_THREADS=1, and `threadpoolctl` enforces it inside the task); ray-traced
  backends get Dr.Jit's thread count set to cores // workers.
"""
from __future__ import annotations

import fcntl
import hashlib
import json
import os
import time
import traceback
import warnings
from dataclasses import dataclass, field
from pathlib import Path

from processing.atomic import write_text_atomic
from processing.io.dataset_store import (ERRORS, PLAN, SHARDS, append_jsonl, check_record, read_shard_entries,
                                      remove_orphans, scan_shards, write_index, write_shard)
from processing.errors import DatasetFormatError, InputError
from rtchannel.errors import ConfigError
from rtchannel.dataset.plan import Plan, WorkItem, expand

THREAD_ENV = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1",
              "NUMEXPR_NUM_THREADS": "1", "VECLIB_MAXIMUM_THREADS": "1"}
# Dask's nanny sets MALLOC_TRIM_THRESHOLD_=65536 in workers, which also freezes glibc's mmap threshold:
# every multi-MB IQ array is then mmapped, page-faulted and unmapped again (+40 % CPU per item measured).
# Large thresholds keep the freed arrays in the heap for reuse (at most ~256 MB held per worker).
MALLOC_ENV = {"MALLOC_TRIM_THRESHOLD_": "268435456", "MALLOC_MMAP_THRESHOLD_": "33554432"}
_WORKER = {"configured": False}


class PlanMismatchError(InputError):
    """The output folder already holds a dataset made from another plan."""


@dataclass
class RunSummary:
    """What a run did: item counts, failures and wall time [s]."""

    total: int
    done_before: int
    done_now: int
    failed: list[dict] = field(default_factory=list)
    seconds: float = 0.0
    workers: int = 1
    quarantined: list[str] = field(default_factory=list)  # shards renamed *.bad on this start
    verify_seconds: float = 0.0  # time spent re-reading and checking the shards on start

    @property
    def complete(self) -> bool:
        return self.done_before + self.done_now == self.total


def tune_malloc() -> bool:
    """Apply MALLOC_ENV in a running process through glibc's mallopt (workers of external clusters start
    with Dask's small trim threshold too). Returns False where there is no glibc."""
    try:
        import ctypes

        libc = ctypes.CDLL("libc.so.6")
        m_trim_threshold, m_mmap_threshold = -1, -3  # glibc's mallopt parameter numbers
        return bool(libc.mallopt(m_trim_threshold, int(MALLOC_ENV["MALLOC_TRIM_THRESHOLD_"]))
                    and libc.mallopt(m_mmap_threshold, int(MALLOC_ENV["MALLOC_MMAP_THRESHOLD_"])))
    except (OSError, AttributeError):
        return False


def configure_worker(backend: str, dr_threads: int | None) -> None:
    """Limit BLAS/OpenMP (and torch, numba, Dr.Jit) threads in this process; idempotent."""
    if _WORKER["configured"]:
        return
    for k, v in THREAD_ENV.items():
        os.environ.setdefault(k, v)
    from threadpoolctl import threadpool_limits

    _WORKER["limits"] = threadpool_limits(limits=1)  # kept alive: the limit holds for the process
    tune_malloc()
    import sys

    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(1)
    import numba  # one worker per core: the kernels' parallel loops (synthesis, facets) would only contend

    numba.set_num_threads(1)
    if backend != "points" and dr_threads:
        from rtchannel.scene.llvm import import_mitsuba

        import_mitsuba()
        import drjit

        drjit.set_thread_count(int(dr_threads))
    _WORKER["configured"] = True


def shard_name(plan_digest: str, items: list[WorkItem]) -> str:
    """Deterministic shard file name of a batch."""
    h = hashlib.sha256((plan_digest + "|" + ",".join(it.item_id for it in items)).encode()).hexdigest()
    return h[:20] + ".h5"


def make_batches(pending: list[WorkItem], per: int) -> list[list[WorkItem]]:
    """Tasks (= shards): `per` items each, except for the mesh backends, where all pending items of one
    motion form one task (they share one backend run, `rtchannel.dataset.items.run_shared`), split only
    beyond 4 x `per` items. Deterministic for a given pending list."""
    from rtchannel.dataset.items import shared_key

    if not pending or pending[0].backend == "points":
        return [pending[i:i + per] for i in range(0, len(pending), per)]
    groups: dict[str, list[WorkItem]] = {}
    for it in pending:
        groups.setdefault(shared_key(it), []).append(it)
    cap = 4 * per
    return [g[i:i + cap] for g in groups.values() for i in range(0, len(g), cap)]


def run_batch(items: list[WorkItem], out: str, plan_digest: str, retries: int, dr_threads: int | None,
              configure: bool = True) -> dict:
    """Run a batch (in a worker; `configure` limits its threads): write its shard; returns
    {"shard", "entries", "errors"}."""
    from rtchannel.dataset.items import run_item, run_shared, shared_key

    if configure:
        configure_worker(items[0].backend if items else "points", dr_threads)
    records: list[dict] = []
    errors: list[dict] = []
    groups: dict[str, list[WorkItem]] = {}
    for it in items:
        groups.setdefault(shared_key(it), []).append(it)
    for group in groups.values():
        if len(group) > 1:
            try:
                records.extend(check_record(r) for r in run_shared(group))
                continue
            except Exception as exc:  # noqa: BLE001 - the items run one by one below, with retries and errors
                warnings.warn(f"shared backend run of {len(group)} items failed ({type(exc).__name__}: {exc}); "
                              "running them one by one", stacklevel=1)
        for it in group:
            for attempt in range(retries + 1):
                try:
                    records.append(check_record(run_item(it)))  # an empty or NaN signature is an item failure
                    break
                except Exception as exc:  # noqa: BLE001 - recorded per item, the run goes on
                    if attempt == retries:
                        errors.append({"item_id": it.item_id, "activity": it.activity, "source": it.source,
                                       "attempts": attempt + 1, "error": f"{type(exc).__name__}: {exc}",
                                       "traceback": traceback.format_exc(limit=4)})
    if not records:
        return {"shard": None, "entries": [], "errors": errors}
    name = shard_name(plan_digest, items)
    path = write_shard(Path(out) / SHARDS / name, records, attrs={"plan": plan_digest})
    entries, _ = read_shard_entries(path)  # as stored: with links and sha256, like the rebuilt index
    return {"shard": name, "entries": entries, "errors": errors}


def _prepare(plan: Plan, out: Path, verify: bool = True) -> tuple[list[dict], str, list[str], float]:
    """(verified entries, plan digest, shards renamed *.bad, seconds spent verifying)."""
    out.mkdir(parents=True, exist_ok=True)
    (out / SHARDS).mkdir(exist_ok=True)
    digest = plan.digest()
    plan_file = out / PLAN
    if plan_file.is_file():
        try:
            old = json.loads(plan_file.read_text())
        except (OSError, ValueError, RecursionError) as e:
            raise DatasetFormatError(f"{plan_file}: unreadable ({type(e).__name__}); move it away or use a new "
                                     "--out folder") from None
        if not isinstance(old, dict):
            raise DatasetFormatError(f"{plan_file}: expected a JSON object; use a new --out folder")
        if old.get("digest") != digest:
            raise PlanMismatchError(f"{out} holds a dataset of another plan (digest {old.get('digest')}, "
                                    f"this plan {digest}); use a new --out folder")
    else:
        write_text_atomic(plan_file, json.dumps({"digest": digest, "plan": plan.model_dump(mode="json")}, indent=1))
    remove_orphans(out)
    t0 = time.perf_counter()
    entries, bad = scan_shards(out, verify=verify, repair=True)
    seconds = time.perf_counter() - t0
    for name in bad:
        warnings.warn(f"{out / SHARDS / name}: unreadable, not a shard, or an array failed its checksum: renamed "
                      f"to {name}.bad; its failed items are computed again", stacklevel=3)
    write_index(out, entries)
    return entries, digest, bad, seconds


def check_scheduler_address(address: str) -> None:
    """`ConfigError` (one line) unless `address` is one Dask can connect to: a scheme it knows (tcp, tls, ws,
    wss, inproc, ucx; none means tcp) and, for the network schemes, a host and a port 1..65535."""
    from distributed.comm.addressing import parse_address, parse_host_port
    from distributed.comm.registry import get_backend

    try:
        scheme, loc = parse_address(address)
        get_backend(scheme)
        if scheme in ("tcp", "tls", "ws", "wss"):
            host, port = parse_host_port(loc, 8786)
            if not host or not 0 < int(port) < 65536:
                raise ValueError("needs HOST:PORT")
    except (ValueError, TypeError) as e:
        raise ConfigError(f"--scheduler {address[:80]!r}: not a Dask scheduler address ({str(e)[:120]}); e.g. "
                          "tcp://HOST:8786") from None


def run_plan(plan: Plan, out: str | Path, *, scheduler: str | None = None, workers: int | None = None,
             retries: int = 2, progress: bool = True, client=None, item_filter=None,
             verify: bool = True) -> RunSummary:
    """Run every unfinished item of `plan` into folder `out`.

    Args:
        plan: a validated plan.
        out: dataset folder (created; must hold this plan's dataset or nothing). On a cluster it must be on
            a filesystem shared with the workers, which write the shards.
        scheduler: address of a running Dask scheduler (e.g. one started by dask-jobqueue); default: a
            local cluster with `workers` single-threaded worker processes (default: the number of cores).
            ``workers=1`` without a scheduler runs in this process (same results, no cluster start-up).
        retries: extra attempts per failing item.
        progress: show a progress bar (items, rate, ETA).
        client: an existing `distributed.Client` to use instead.
        item_filter: optional predicate on `WorkItem`: run (and count) only the items it accepts
            (benchmarks, partial runs).
        verify: on start, check every stored array against its sha256 (default; False only for
            benchmarks: unverified resumes can pass corrupted data on).

    Returns:
        A `RunSummary`. Raises `PlanMismatchError` if `out` holds another plan's dataset, or
        BlockingIOError if another run is writing to `out`.
    """
    out = Path(out)
    t_start = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    lock = open(out / ".lock", "w")
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        lock.close()
        raise BlockingIOError(f"another run is writing to {out}") from None
    try:
        return _run_locked(plan, out, scheduler, workers, retries, progress, client, item_filter, t_start, verify)
    finally:
        fcntl.flock(lock, fcntl.LOCK_UN)
        lock.close()


def _run_locked(plan, out, scheduler, workers, retries, progress, client, item_filter, t_start,
                verify=True) -> RunSummary:
    from tqdm import tqdm

    done, digest, quarantined, verify_s = _prepare(plan, out, verify)
    items = [it for it in expand(plan) if item_filter is None or item_filter(it)]
    done_ids = {e["item_id"] for e in done}
    pending = [it for it in items if it.item_id not in done_ids]
    batches = make_batches(pending, plan.storage.items_per_shard)
    n_workers = workers or os.cpu_count() or 1
    summary = RunSummary(total=len(items), done_before=len(items) - len(pending), done_now=0, workers=n_workers,
                         quarantined=quarantined, verify_seconds=verify_s)
    write_text_atomic(out / ERRORS, "")  # failures of this run only; earlier failures are retried
    bar = tqdm(total=len(pending), unit="item", disable=not progress or None, dynamic_ncols=True,
               desc=f"{plan.name} ({summary.done_before}/{len(items)} done)")

    def record(res: dict) -> None:
        summary.done_now += len(res["entries"])
        summary.failed.extend(res["errors"])
        if res["entries"]:
            append_jsonl(out / "index.jsonl", res["entries"])  # the shard is already renamed
        if res["errors"]:
            append_jsonl(out / ERRORS, [{k: v for k, v in e.items() if k != "traceback"} for e in res["errors"]])
        bar.update(len(res["entries"]) + len(res["errors"]))
        bar.set_postfix(failed=len(summary.failed))

    try:
        if batches and client is None and scheduler is None and n_workers == 1:
            from threadpoolctl import threadpool_limits

            tune_malloc()
            with threadpool_limits(limits=1):  # as in the Dask workers, so results are bit-identical
                for b in batches:
                    record(run_batch(b, str(out), digest, retries, None, configure=False))
        elif batches:
            _run_dask(batches, out, digest, retries, plan.backend, n_workers, scheduler, client, record, summary)
    finally:
        bar.close()
        entries, _ = scan_shards(out)
        write_index(out, entries)  # sorted, deduplicated: heals a kill between shard rename and index append
    final_ids = {e["item_id"] for e in entries}
    summary.failed = sorted((e for e in summary.failed if e["item_id"] not in final_ids), key=lambda e: e["item_id"])
    write_text_atomic(out / ERRORS, "".join(json.dumps({k: v for k, v in e.items() if k != "traceback"}, sort_keys=True)
                                      + "\n" for e in summary.failed))
    summary.seconds = time.perf_counter() - t_start
    return summary


def _run_dask(batches, out, digest, retries, backend, n_workers, scheduler, client, record, summary) -> None:
    from distributed import Client, LocalCluster, as_completed

    cluster = None
    own_client = client is None
    if client is None:
        if scheduler:
            check_scheduler_address(scheduler)
            client = Client(scheduler)
        else:
            import dask

            # pre-spawn: these must be in the environment when the worker process starts
            spawn_env = {f"distributed.nanny.pre-spawn-environ.{k}": v for k, v in {**THREAD_ENV, **MALLOC_ENV}.items()}
            with dask.config.set(spawn_env):
                cluster = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                                       dashboard_address=None)
            client = Client(cluster)
    try:
        n_live = max(1, len(client.scheduler_info().get("workers", {})) or n_workers)
        summary.workers = n_live
        dr_threads = max(1, (os.cpu_count() or 1) // n_live)
        futures = {client.submit(run_batch, b, str(out), digest, retries, dr_threads, pure=False, retries=1):
                   b for b in batches}
        ac = as_completed(list(futures))
        for fut in ac:
            batch = futures.pop(fut)
            if fut.status == "finished":
                record(fut.result())
            elif len(batch) > 1:  # the task itself died (e.g. a worker crashed): retry item by item
                for it in batch:
                    f = client.submit(run_batch, [it], str(out), digest, retries, dr_threads, pure=False, retries=1)
                    futures[f] = [it]
                    ac.add(f)
            else:
                try:
                    exc = fut.exception()
                except BaseException as e:  # noqa: BLE001 - e.g. a cancelled future
                    exc = e
                record({"entries": [], "errors": [{"item_id": batch[0].item_id, "activity": batch[0].activity,
                                                   "source": batch[0].source, "attempts": retries + 1,
                                                   "error": f"task failed: {type(exc).__name__}: {exc}"}]})
    finally:
        if own_client:
            client.close()
            if cluster is not None:
                cluster.close()
