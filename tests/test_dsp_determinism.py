"""The DSP gives the same bytes for any BLAS thread count (issue 13): the same seed, the same signature.

Each case runs in a fresh interpreter with OPENBLAS_NUM_THREADS (and OMP/MKL) set before numpy loads,
since the BLAS reads them once. The mean-velocity case is the one that failed with `weights @ p_vt`
(complex matrix-vector product over 500 windows: different last bits with 1 and 2 threads, measured
with OpenBLAS 0.3.31); the signature case runs the whole slow-time chain on synthetic IQ.
"""
import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]

SCRIPT = r"""
import hashlib
import numpy as np
from processing.dsp.signatures import DSPConfig, mean_velocity, signatures
from processing.radar.waveform import Waveform

h = hashlib.sha256()
rng = np.random.default_rng(1)
V, T = 64, 500
vel = (np.arange(V) - V // 2) * 0.2
for order in "CF":  # a peaked p(v,t) (the unwrapped branch is used) in both memory layouts
    p = np.exp(-((vel[:, None] - rng.uniform(-5, 5, T)) / 0.6) ** 2)
    p = np.asarray(p / p.sum(0), order=order)
    for mode in ("seed", "unwrapped"):
        h.update(mean_velocity(p, vel, 6.4, DSPConfig(mean_velocity=mode)).tobytes())
wf = Waveform()
t = np.arange(4096)[:, None] * wf.pri_s
m = np.arange(wf.samples_per_chirp)[None, :]
iq = sum(np.exp(2j * np.pi * (wf.start_hz * tau + wf.slope * tau * m / wf.fs))
         for tau in (2 * (r0 - v * t) / 3e8 for r0, v in ((2.0, 1.3), (3.1, -0.7), (2.6, 2.9))))
iq = (iq + 0.05 * (rng.standard_normal(iq.shape) + 1j * rng.standard_normal(iq.shape))).astype(np.complex64)
for range_sum in ("coherent", "incoherent", "magnitude"):
    s = signatures(iq, wf, DSPConfig(range_sum=range_sum, hop_chirps=8, mean_velocity="unwrapped"))
    for a in (s.p_vt, s.mean_velocity, s.range_distribution, s.power):
        h.update(np.ascontiguousarray(a).tobytes())
print(h.hexdigest())
"""


def _digest(threads: int) -> str:
    env = {**os.environ, "PYTHONPATH": str(REPO), "OPENBLAS_NUM_THREADS": str(threads),
           "OMP_NUM_THREADS": str(threads), "MKL_NUM_THREADS": str(threads)}
    run = subprocess.run([sys.executable, "-c", SCRIPT], cwd=REPO, env=env, capture_output=True, text=True,
                         timeout=600)
    assert run.returncode == 0, run.stderr[-2000:]
    return run.stdout.strip()


def test_same_bytes_with_one_and_two_blas_threads():
    one, two = _digest(1), _digest(2)
    assert len(one) == 64 and one == two


CHAIN = r"""
import hashlib
import numpy as np
from rtchannel.motion.procedural import generate
from rtchannel.pipeline import simulate

h = hashlib.sha256()
m = generate("fall", duration=0.8, pad_before=0.2, pad_after=0.2)
for backend, opts in (("points", {}), ("facets", {"lod": "2k"})):
    for keep in (False, True):
        res = simulate(m, backend=backend, keep_iq=keep, **opts)
        for s in res.signatures.values():
            for a in (s.p_vt, s.mean_velocity, s.range_distribution, s.power):
                h.update(np.ascontiguousarray(a).tobytes())
print(h.hexdigest())
"""


def test_whole_chain_same_bytes_with_one_and_two_blas_threads():
    """`simulate` (synthesis projections, receiver noise, DSP; both routes, points and facets): the
    pipeline pins BLAS to one thread, so the environment's thread count cannot change a byte."""
    digests = []
    for threads in (1, 2):
        env = {**os.environ, "PYTHONPATH": str(REPO), "OPENBLAS_NUM_THREADS": str(threads),
               "OMP_NUM_THREADS": str(threads), "MKL_NUM_THREADS": str(threads)}
        run = subprocess.run([sys.executable, "-c", CHAIN], cwd=REPO, env=env, capture_output=True, text=True,
                             timeout=900)
        assert run.returncode == 0, run.stderr[-2000:]
        digests.append(run.stdout.strip().splitlines()[-1])
    assert len(digests[0]) == 64 and digests[0] == digests[1]
