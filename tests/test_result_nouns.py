"""Results are nouns (DESIGN.md): public objects print a short summary, save and load as pairs returning the
same type, expose labelled arrays and plot onto an ``ax=`` the caller gives."""
import dataclasses

import numpy as np
import pytest

from processing.errors import InputError
from processing.pathset import PathSet
from rtchannel import Motion


def test_motion_is_immutable_and_replace_validates():
    m = Motion.procedural("fall", seed=0)
    with pytest.raises(dataclasses.FrozenInstanceError):
        m.positions = m.positions[:, :5]  # another shape: once passed silently
    with pytest.raises(ValueError, match="read-only"):
        m.positions[0, 0, 0] = 1.0
    with pytest.raises(InputError, match="shapes disagree"):
        dataclasses.replace(m, positions=m.positions[:, :5])
    other = dataclasses.replace(m, activity="sit")
    assert other.activity == "sit" and m.activity == "fall"
    np.testing.assert_array_equal(other.positions, m.positions)
    mine = np.zeros((2, 31, 3))
    Motion(m.rig, 60.0, np.tile(np.eye(3), (2, 31, 1, 1)), mine)
    mine[0, 0, 0] = 1.0  # the caller's own array stays writeable


# ------------------------------------------------------------------------------------------ shared objects
@pytest.fixture(scope="module")
def walk():
    return Motion.procedural("walk", duration=2.0, seed=0)


@pytest.fixture(scope="module")
def channel(walk):
    from rtchannel import Radar, trace

    return trace(walk, Radar.seed(direction=1), backend="points")


@pytest.fixture(scope="module")
def result(channel):
    from rtchannel import synthesise

    return synthesise(channel, keep_iq=True)


def _frame_local_pathset() -> "PathSet":
    """A Sionna-like path set: no ids, delay rates, absent paths (NaN delay, gain 0)."""
    rng = np.random.default_rng(0)
    delays = rng.uniform(1e-8, 4e-8, (7, 5))
    gains = rng.normal(size=(7, 5)) + 1j * rng.normal(size=(7, 5))
    delays[2, 3], gains[2, 3] = np.nan, 0.0
    return PathSet(np.arange(7) / 30.0, delays, gains, delay_rates=rng.normal(0, 1e-8, (7, 5)), link="bistatic")


# ------------------------------------------------------------------------------------------ summaries
def test_no_public_object_prints_more_than_600_characters(walk, channel, result):
    """Before: repr(SimulationResult) was 38,337 characters, Signature 18,531, PathSets 10,379 (whole arrays)."""
    import rtchannel
    from processing.radar.receiver import ANCORTEK_2400T2R4, ANCORTEK_580AD, LeakageConfig
    from rtchannel import Link, Radar, Scene

    sit = Motion.procedural("sit", seed=0)
    many = Radar(links=[Link(name=f"l{k}", tx=(3.0, 0.1 * k, 1.0), rx=(0.0, -3.0, 1.0)) for k in range(40)])
    objects = {"Motion": walk, "Rig": walk.rig, "Radar": Radar.seed(), "Radar.glasgow": Radar.glasgow(),
               "Radar, 40 bistatic links": many, "Link": many.links[0], "Scene": Scene.room().with_chair_for(sit),
               "Waveform": rtchannel.Waveform(), "DSPConfig.glasgow": rtchannel.DSPConfig.glasgow(),
               "ReceiverConfig": ANCORTEK_2400T2R4.receiver, "RadarHardware": ANCORTEK_580AD,
               "LeakageConfig": LeakageConfig(), "GaussianBeam": ANCORTEK_2400T2R4.antenna,
               "YagiBeam": ANCORTEK_580AD.antenna, "Isotropic": rtchannel.Isotropic(), "PathSet": channel["radar1"],
               "PathSet, frame-local": _frame_local_pathset(), "PathSets": channel,
               "Signature": result.signatures["radar1"],
               "LinkResult": result.links["radar1"], "SimulationResult": result}
    long = {k: len(repr(v)) for k, v in objects.items() if len(repr(v)) > 600}
    assert not long, long
    # what, shape, duration, links, units
    assert "walk" in repr(result) and "radar1, radar2" in repr(result) and "velocity x" in repr(result)
    assert f"{walk.n_frames} frames over {walk.duration:.3g} s" in repr(channel) and "2 links" in repr(channel)
    assert "[64 velocity x" in repr(result.signatures["radar1"]) and "m/s" in repr(result.signatures["radar1"])
    assert f"{walk.n_frames} frames" in repr(walk) and f"{walk.duration:.2f} s" in repr(walk)
    assert "40 links" in repr(many) and "24.125 GHz" in repr(many)


# ------------------------------------------------------------------------------------------ labelled arrays
def test_signature_to_xarray_has_velocity_time_and_range_coordinates(result):
    sig = result.signatures["radar1"]
    ds = sig.to_xarray()
    assert ds.p_vt.dims == ("velocity", "time") and ds.range_distribution.dims == ("range", "time")
    np.testing.assert_array_equal(ds.velocity, sig.velocity)
    np.testing.assert_array_equal(ds.time, sig.time)
    np.testing.assert_array_equal(ds.range, sig.range)
    assert ds.velocity.attrs["units"] == "m/s" and ds.time.attrs["units"] == "s" and ds.range.attrs["units"] == "m"
    k = sig.time.size // 2  # label-based selection gives the same column as the index
    np.testing.assert_array_equal(ds.p_vt.sel(time=sig.time[k]).values, sig.p_vt[:, k])
    assert ds.range_doppler.dims == ("range", "rd_velocity", "rd_time")
    both = result.to_xarray()
    assert list(both.link.values) == ["radar1", "radar2"] and both.p_vt.dims == ("link", "velocity", "time")
    ps = result.links["radar1"]
    assert ps.chirp_times.size == result.iq["radar1"].shape[0]


def test_pathset_to_xarray_labels_paths_by_id(channel):
    ds = channel.to_xarray("radar1")
    assert ds.delay.dims == ("time", "path") and ds.delay.attrs["units"] == "s"
    np.testing.assert_array_equal(ds.path, channel["radar1"].ids)
    np.testing.assert_array_equal(ds.gain.values, channel["radar1"].gains)


# ------------------------------------------------------------------------------------------ save / load pairs
def test_simulation_result_load_equals_what_was_saved(result, tmp_path):
    from rtchannel import SimulationResult

    path = result.save(tmp_path / "signature.h5")
    back = SimulationResult.load(path)
    assert back == result
    assert back.iq["radar2"].dtype == result.iq["radar2"].dtype and back.timing == result.timing
    changed = SimulationResult.load(path)
    changed.links["radar2"].signature.p_vt[0, 0] += 1e-12  # the comparison can fail
    assert changed != result


def test_channel_round_trips_bit_identically(channel, tmp_path):
    from rtchannel import PathSets

    back = PathSets.load(channel.save(tmp_path / "channel.h5"))
    assert back == channel and back.radar == channel.radar and list(back) == list(channel)
    for name in channel:
        for key in ("times", "delays", "gains", "ids"):
            a, b = getattr(channel[name], key), getattr(back[name], key)
            assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), (name, key)
    assert back.config["backend"] == "points" and back.config["motion"] == channel.config["motion"]
    # a frame-local link (no ids, delay rates, an absent path with a NaN delay), a bistatic radar
    from rtchannel import Link, Radar

    ps = _frame_local_pathset()
    bistatic = Radar(links=[Link(name="bistatic", tx=(2.0, -1.0, 1.2), rx=(-1.0, 2.5, 0.9))], receiver=None)
    local = PathSets({"bistatic": ps}, bistatic, {"backend": "sionna", "note": ("a", 1)}, {"backend": 0.5})
    back = PathSets.load(local.save(tmp_path / "local.h5"))
    assert back == local and back["bistatic"].ids is None
    assert back["bistatic"].delay_rates.tobytes() == ps.delay_rates.tobytes()
    assert np.isnan(back["bistatic"].delays[2, 3])
    other = PathSets.load(tmp_path / "local.h5")
    other["bistatic"].gains[0, 0] += 1e-15
    assert other != local


def test_a_loaded_channel_synthesises_like_the_traced_one(channel, result, tmp_path):
    from rtchannel import PathSets, synthesise

    again = synthesise(PathSets.load(channel.save(tmp_path / "c.h5")), keep_iq=True)
    assert again.links == result.links


# ------------------------------------------------------------------------------------------ figures
def test_plots_draw_on_the_callers_axes_and_write_nothing(result, tmp_path, monkeypatch):
    from matplotlib.figure import Figure

    from rtchannel import plot_mean_velocity, plot_pvt, plot_range, plot_range_doppler, save_figure

    monkeypatch.chdir(tmp_path)
    fig = Figure()
    ax1, ax2 = fig.subplots(1, 2)
    assert plot_pvt(result.signatures, ax=[ax1, ax2]) is fig
    assert ax1.get_title() == "radar1: micro-Doppler p(v,t)" and ax1.images
    assert plot_range(result.signatures["radar2"], ax=ax2) is fig
    assert plot_mean_velocity(result.signatures, ax=ax1) is fig
    assert isinstance(plot_range_doppler(result.signatures), Figure)
    assert result.plot(ax=[ax1, ax2], kind="range") is fig
    with pytest.raises(InputError, match="2 Axes needed"):
        plot_pvt(result.signatures, ax=ax1)
    assert not any(tmp_path.iterdir())  # drawing wrote nothing
    assert save_figure(fig, tmp_path / "a.png").stat().st_size > 0
    assert sorted(p.name for p in result.save_figures(tmp_path / "f")) == [
        "mean_velocity.png", "pvt.png", "range.png", "range_doppler.png"]


def test_old_names_work_one_release_with_a_deprecation_warning(result, tmp_path):
    import rtchannel

    path = result.save(tmp_path / "s.h5")
    with pytest.warns(DeprecationWarning, match="SimulationResult.load"):
        attrs, sigs = rtchannel.load_signatures(path)
    assert sigs["radar1"] == result.signatures["radar1"] and attrs["backend"] == "points"
    with pytest.warns(DeprecationWarning, match="save_figures"):
        pngs = result.plot(tmp_path / "old")
    assert sorted(p.name for p in pngs)[0] == "mean_velocity.png"
    with pytest.warns(DeprecationWarning, match="save_figures"):
        rtchannel.plot_signatures(result.signatures, tmp_path / "old2")
    with pytest.warns(DeprecationWarning, match="save_figure"):
        assert rtchannel.plot_pvt(result.signatures, tmp_path / "p.png").is_file()
    with pytest.warns(DeprecationWarning, match="moved to processing.fast_time"):
        from processing.dsp.fast_time import max_range  # noqa: F401
