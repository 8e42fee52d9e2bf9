#!/usr/bin/env bash
# A regular install works: build the wheel, install it into a fresh virtual environment, and from an empty
# folder run `rtchannel simulate` (points and facets) and the Python API. Used by CI after the test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-python3.11}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$PYTHON" -m venv "$work/venv"
"$work/venv/bin/pip" install -q --upgrade pip
"$work/venv/bin/pip" install -q torch==2.13.0            # first: nothing may pull another torch build
"$work/venv/bin/pip" wheel -q --no-deps -w "$work/dist" .
"$work/venv/bin/pip" install -q "$work"/dist/rtchannel-*.whl
mkdir "$work/empty" && cd "$work/empty"
export RTCHANNEL_DATA_CACHE="$work/cache"                 # nothing third-party is needed below
"$work/venv/bin/rtchannel" simulate --activity walk --backend points --out w_points
# --accuracy fast: the shipped calibration table (package data) chooses the 2k mesh for the seed radar
"$work/venv/bin/rtchannel" simulate --activity walk --backend facets --accuracy fast --out w_facets --no-plots
"$work/venv/bin/python" - <<'PY'
import rtchannel, pathlib
from rtchannel import Motion, Radar, simulate
assert "site-packages" in rtchannel.__file__, rtchannel.__file__
res = simulate(Motion.procedural("sit", seed=0), Radar.seed(direction=1), backend="points")
res.save("api/signature.h5")
assert pathlib.Path("api/signature.h5").is_file() and pathlib.Path("w_points/signature.h5").is_file()
assert pathlib.Path("w_facets/signature.h5").is_file()
from rtchannel.accuracy import shipped_tables
assert len(shipped_tables()) >= 2, "calibration tables missing from the wheel"
print("wheel check: simulate (points, facets) and the API ran from an empty folder")
PY
