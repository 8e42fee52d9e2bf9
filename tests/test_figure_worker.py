"""`processing.plots.figure_worker.FigureWorker`: the figures of `rtchannel simulate` drawn in a forked child,
which must give the files the in-process route gives, pass its errors on, and never fork where a lock could be
held by another thread (each check runs in a fresh interpreter: this test process has threads)."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_SIGNATURES = """
import numpy as np
from processing.dsp.signatures import Signature
t, v, r = np.linspace(0.05, 1.0, 20), np.linspace(-6, 6, 32, endpoint=False), np.linspace(0.5, 5, 16)
p = np.exp(-((v[:, None] - np.sin(t)[None, :]) ** 2))
sig = Signature(time=t, velocity=v, p_vt=p / p.sum(axis=0), mean_velocity=np.sin(t), range=r,
                range_distribution=np.full((16, 20), 1 / 16), valid=np.ones(20, bool), power=np.ones(20))
sigs = {"radar1": sig}
"""


def _run(code: str) -> str:
    path = os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    env = {**os.environ, "PYTHONPATH": path}
    r = subprocess.run([sys.executable, "-c", _SIGNATURES + code], cwd=ROOT, env=env, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr[-2000:]
    return r.stdout


def test_child_writes_the_same_files_as_this_process(tmp_path):
    out = _run(f"""
from processing.plots.figure_worker import FigureWorker
from processing.plots.signatures import save_figures
with FigureWorker() as w:
    assert w.in_child
    paths = w.save_figures(sigs, {str(tmp_path / 'child')!r}, "t")
here = save_figures(sigs, {str(tmp_path / 'here')!r}, "t")
assert [p.name for p in paths] == [p.name for p in here] == ["pvt.png", "mean_velocity.png", "range.png"]
assert all(a.read_bytes() == b.read_bytes() for a, b in zip(paths, here))
print("ok")
""")
    assert out.strip().endswith("ok")


def test_errors_of_the_child_reach_the_caller(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")  # a folder cannot be made under a file: save_figures raises in the child
    out = _run(f"""
from processing.plots.figure_worker import FigureWorker
with FigureWorker() as w:
    assert w.in_child
    try:
        w.save_figures(sigs, {str(blocker / 'sub')!r}, "t")
    except OSError as e:
        print("raised", type(e).__name__)
""")
    assert "raised" in out


def test_no_fork_while_another_thread_runs(tmp_path):
    out = _run(f"""
import threading
from processing.plots.figure_worker import FigureWorker, can_fork
stop = threading.Event()
t = threading.Thread(target=stop.wait)
t.start()
with FigureWorker() as w:
    assert not can_fork() and not w.in_child
    assert len(w.save_figures(sigs, {str(tmp_path / "here")!r}, "t")) == 3
stop.set()
t.join()
print("ok")
""")
    assert out.strip().endswith("ok")
