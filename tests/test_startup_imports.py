"""Start-up cost of the command line: which heavy libraries a command loads (the speed itself is measured in
benchmarks/bench_startup.py, not here).

`rtchannel --help` and the argument parser of every command load none of the heavy libraries; the facets
backend loads Mitsuba but not Sionna RT (nor its preview libraries) nor torch; the points backend's whole chain
(procedural motion, paths, synthesis, DSP, signature.h5) runs without the ray tracer (Mitsuba, Dr.Jit, Sionna RT),
the mesh library (trimesh), numba or torch, and with the default (rectangular) tapers and moving-average MTI
without scipy.signal; its figures use matplotlib without pyplot.
Each check runs in a fresh interpreter: this test process has long since imported everything.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
HEAVY = ("torch", "mitsuba", "drjit", "sionna", "trimesh", "matplotlib")

# Appended to each probe: the loaded modules among `names` (top-level packages, or exact dotted modules),
# as the last line of stdout.
_REPORT = """
import json, sys
_names = {names!r}
print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in _names or m in _names)))
"""


def _loaded(code: str, names, timeout: float = 300.0) -> list[str]:
    """Modules among `names` loaded after running `code` in a fresh interpreter of this worktree."""
    env = {**os.environ,
           "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)}
    env.pop("MPLBACKEND", None)
    r = subprocess.run([sys.executable, "-c", code + _REPORT.format(names=set(names))], cwd=ROOT, env=env,
                       capture_output=True, text=True, timeout=timeout)
    assert r.returncode == 0, r.stderr[-2000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_probe_sees_heavy_imports():
    # The probe itself must be able to fail: the facets backend module does load numba (its kernels).
    assert "numba" in _loaded("import rtchannel.backends.facets", {"numba"})


def test_parser_loads_no_heavy_library():
    code = "import rtchannel.cli as c\nc.build_parser().parse_args(['simulate', '--out', 'x'])\n"
    assert _loaded(code, {*HEAVY, "scipy", "numba", "h5py"}) == []


def test_points_simulate_loads_no_ray_tracer_nor_torch(tmp_path):
    out = tmp_path / "walk"
    code = (f"from rtchannel.cli import main\n"
            f"assert main(['simulate', '--backend', 'points', '--activity', 'walk', '--duration', '2.0', "
            f"'--out', {str(out)!r}, '--quiet', '--no-plots']) == 0\n")
    loaded = _loaded(code, {*HEAVY, "numba", "scipy.signal"})
    assert loaded == []
    assert (out / "signature.h5").is_file() and not (out / "pvt.png").exists()


def test_points_figures_use_matplotlib_without_pyplot(tmp_path):
    out = tmp_path / "walk"
    code = (f"from rtchannel.cli import main\n"
            f"assert main(['simulate', '--backend', 'points', '--activity', 'walk', '--duration', '2.0', "
            f"'--out', {str(out)!r}, '--quiet']) == 0\n")
    loaded = _loaded(code, {*HEAVY, "matplotlib.pyplot"})
    assert "matplotlib" in loaded and "matplotlib.pyplot" not in loaded
    assert not set(loaded) & {"torch", "mitsuba", "drjit", "sionna", "trimesh"}
    for png in ("pvt.png", "mean_velocity.png", "range.png", "range_doppler.png"):
        assert (out / png).stat().st_size > 10_000


def test_facets_simulate_builds_the_scene_once_without_sionna(tmp_path):
    # One RTScene (one Mitsuba scene load) per process, whatever the CLI does around the backend (chair
    # fitting, clearance checks): counted by wrapping the constructor before anything runs. The scene is
    # loaded with Mitsuba alone: Sionna RT's package (and the matplotlib.pyplot, IPython, ipywidgets and
    # pythreejs it imports for its previews) is never loaded, nor torch.
    code = (f"from rtchannel.scene import rt_scene\n"
            f"n = [0]\n"
            f"init = rt_scene.RTScene.__init__\n"
            f"def counted(self, *a, **k):\n"
            f"    n[0] += 1\n"
            f"    init(self, *a, **k)\n"
            f"rt_scene.RTScene.__init__ = counted\n"
            f"from rtchannel.cli import main\n"
            f"assert main(['simulate', '--backend', 'facets', '--lod', '2k', '--activity', 'walk', '--duration', "
            f"'1.0', '--out', {str(tmp_path / 'f')!r}, '--quiet', '--no-plots']) == 0\n"
            f"assert n[0] == 1, n\n")
    loaded = _loaded(code, {"torch", "sionna", "matplotlib.pyplot", "IPython", "ipywidgets", "pythreejs", "mitsuba"},
                     timeout=900.0)
    assert "mitsuba" in loaded and {m.split(".")[0] for m in loaded} == {"mitsuba"}


@pytest.mark.parametrize("name", ["boxcar", "box", "ones", "rect", "rectangular"])
@pytest.mark.parametrize("fftbins", [True, False])
def test_rectangular_taper_is_scipys(name, fftbins):
    from scipy.signal import get_window as scipy_get_window

    from processing.windows import get_window

    for n in (1, 2, 7, 64, np.int64(128)):
        ours, theirs = get_window(name, n, fftbins), scipy_get_window(name, n, fftbins=fftbins)
        assert ours.dtype == theirs.dtype and np.array_equal(ours, theirs)


def test_window_names_are_scipys():
    from scipy.signal.windows import _windows

    from processing.windows import NAMED, is_window_name

    plain = {k for k, (_, needs_args) in _windows._WIN_FUNCS.items() if needs_args is not True}
    assert NAMED == plain
    assert is_window_name("hann") and not is_window_name("kaiser") and not is_window_name("no-such-window")
