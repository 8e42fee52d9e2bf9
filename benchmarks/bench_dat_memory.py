"""Peak memory and time of the Ancortek `.dat` reader against the file size.

    python benchmarks/bench_dat_memory.py [--samples 2000000] [--repo PATH]

Writes a synthetic one-channel recording (128 samples per sweep, ~31 bytes of text per sample), then
reads it in a fresh subprocess (cwd = --repo, default this checkout, so an older checkout can be
measured the same way) and reports the growth of the peak resident set size (VmHWM after the call
minus the RSS before it) as a multiple of the file size.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

CHILD = r"""
import json, sys, time
from processing.realdata.ancortek import read_dat
def rss_kb():
    for line in open("/proc/self/status"):
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
before = rss_kb()
t0 = time.perf_counter()
rec = read_dat(sys.argv[1])
dt = time.perf_counter() - t0
peak = int(next(l.split()[1] for l in open("/proc/self/status") if l.startswith("VmHWM:")))
print(json.dumps({"seconds": dt, "peak_growth_bytes": (peak - before) * 1024, "sweeps": rec.header["n_sweeps"]}))
"""


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=2_000_000)
    ap.add_argument("--repo", type=Path, default=Path(__file__).resolve().parents[1])
    args = ap.parse_args()
    import numpy as np

    n = args.samples // 128 * 128
    rng = np.random.default_rng(0)
    iq = (rng.standard_normal(n) + 1j * rng.standard_normal(n)).astype(np.complex64) * 1e-2
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "bench.dat"
        re_s = np.char.mod("%.8e", iq.real.astype(np.float64))
        im_s = np.char.mod("%+.8e", iq.imag.astype(np.float64))
        rows = np.char.add(np.char.add(re_s, im_s), "i").tolist()
        path.write_text("24.125\n1.0\n128\n250\n" + "\n".join(rows) + "\n")
        size = path.stat().st_size
        del iq, re_s, im_s, rows
        out = subprocess.run([sys.executable, "-c", CHILD, str(path)], cwd=args.repo, capture_output=True, text=True,
                             check=True)
        res = json.loads(out.stdout)
    print(f"repo {args.repo}: file {size / 2**20:.1f} MiB, {n} samples; read in {res['seconds']:.2f} s; "
          f"peak RSS growth {res['peak_growth_bytes'] / 2**20:.1f} MiB = {res['peak_growth_bytes'] / size:.2f} x file")


if __name__ == "__main__":
    main()
