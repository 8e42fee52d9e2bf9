"""Synthesis apart from DSP: the DSP settings are given at `synthesise` (default the radar's), stored raw IQ is
reprocessed by the exported `process`, and the call path of a simulation goes from synthesis to DSP once,
never back (the fast-time model both use sits below them, in `processing.fast_time`)."""
import importlib.util
from pathlib import Path

import numpy as np
import pytest

from rtchannel import DSPConfig, Motion, Radar, process, synthesise, trace

REPO = Path(__file__).resolve().parents[1]
OTHER = DSPConfig(window_chirps=128, hop_chirps=64, range_sum="incoherent")


@pytest.fixture(scope="module")
def channel():
    return trace(Motion.procedural("fall", seed=3), Radar.seed(direction=1), backend="points")


@pytest.fixture(scope="module")
def kept(channel):
    return synthesise(channel, keep_iq=True)


def test_process_gives_the_signatures_of_the_kept_iq_bit_for_bit(channel, kept):
    again = process(kept.iq, channel.radar)
    assert again.keys() == kept.signatures.keys()
    for name, sig in kept.signatures.items():
        assert again[name] == sig  # every array, bit for bit
    assert process(kept.iq["radar1"], channel.radar) == kept.signatures["radar1"]


def test_dsp_given_at_synthesise_defaults_to_the_radars(channel, kept):
    same = synthesise(channel, dsp=channel.radar.dsp, keep_iq=True)
    assert same.links == kept.links and same.config == kept.config  # (timing differs run to run)
    other = synthesise(channel, dsp=OTHER, keep_iq=True)
    assert other.config["radar"]["dsp"]["window_chirps"] == 128  # the settings used are recorded
    assert other.config["radar"]["dsp"]["range_sum"] == "incoherent"
    assert other.signatures["radar1"].p_vt.shape[1] < kept.signatures["radar1"].p_vt.shape[1]
    # the same channel and noise seed give the same IQ whatever the DSP: reprocessing it equals synthesising anew
    for name in kept.iq:
        np.testing.assert_array_equal(other.iq[name], kept.iq[name])
    assert process(kept.iq, channel.radar, dsp=OTHER) == other.signatures
    assert process(kept.iq, channel.radar, dsp=OTHER.model_dump()) == other.signatures  # a dict of fields works too


def test_projection_route_agrees_with_reprocessed_iq(channel, kept):
    """Without kept IQ the DSP's fast-time projection is synthesised straight from the paths; it equals the
    IQ route up to float rounding (tests/test_synthesis_projection.py): p(v,t) columns sum to 1, so 1e-6
    absolute is ~1e-6 of a column, far above complex64 rounding (6e-8) and far below any signal change."""
    direct = synthesise(channel, dsp=OTHER)
    again = process(kept.iq, channel.radar, dsp=OTHER)
    for name, sig in direct.signatures.items():
        np.testing.assert_allclose(sig.p_vt, again[name].p_vt, rtol=0, atol=1e-6)


def _crossings_script():
    spec = importlib.util.spec_from_file_location("stage_crossings", REPO / "scripts" / "stage_crossings.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.parametrize("synthesis", ["exact", "grid"])
def test_the_call_path_goes_from_synthesis_to_dsp_once(synthesis):
    """Before the fast-time model had a neutral home the path turned 15 times on the exact route and 17 on the
    gridded one (synthesis called the DSP's fast-time functions, chunk by chunk); now it is synthesis, then DSP."""
    path = _crossings_script().stage_path("points", synthesis)
    assert [stage for stage, _ in path] == ["synthesis", "dsp"], path


def test_simulate_radars_is_built_on_trace_with_its_progress_and_warnings():
    """One `trace` for all radars, then `synthesise` per radar: the points backend's scene warning comes through,
    progress counts every radar's chirps, and each result equals the radar's own `simulate`."""
    import warnings

    from rtchannel import Scene, simulate, simulate_radars

    motion = Motion.procedural("fall", seed=3)
    radars = [Radar.seed(direction=d) for d in (1, 7)]
    done = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        results = simulate_radars(motion, radars, "points", scene=Scene.room(), progress=done.append)
    assert any("free-space model" in str(w.message) for w in caught)
    n_chirps = sum(r.links[name].chirp_times.size for r in results for name in r.links)
    assert sum(done) == n_chirps > 0
    for radar, res in zip(radars, results):
        alone = simulate(motion, radar, "points")
        assert res.links == alone.links and res.config["traced_with_radars"] == 2
