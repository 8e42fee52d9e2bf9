"""Simulate a walk toward the seed's Radar 1 through the Python API; write signature.h5 and the figures.

Run:  .venv/bin/python examples/simulate_walk.py [OUT_DIR]      (default: a new temporary folder, never the checkout)
The same simulation from the command line:
      .venv/bin/rtchannel simulate --activity walk --backend points --direction 1 --seed 0 --out OUT_DIR
"""
from __future__ import annotations

import sys
import tempfile
from pathlib import Path

from rtchannel import Motion, Radar, simulate


def main(out_dir: str | Path | None = None) -> Path:
    """Simulate, save and plot into `out_dir` (default a new temporary folder); returns the signature file."""
    out_dir = Path(tempfile.mkdtemp(prefix="rtchannel-walk-")) if out_dir is None else Path(out_dir)
    motion = Motion.procedural("walk", height=1.75, seed=0)  # 4 m toward Radar 1, centred on the origin
    radar = Radar.seed(direction=1)  # the seed's 2x2 distributed MIMO radar, 24.125 GHz
    result = simulate(motion, radar, backend="points")
    sig = result.signatures["radar1"]
    print(f"radar1: {sig.p_vt.shape[1]} windows, peak mean radial velocity {sig.mean_velocity.max():.2f} m/s")
    path = result.save(out_dir / "signature.h5")
    for png in result.save_figures(out_dir):
        print(f"wrote {png}")
    print(f"wrote {path}")
    return path


if __name__ == "__main__":
    main(*sys.argv[1:2])
