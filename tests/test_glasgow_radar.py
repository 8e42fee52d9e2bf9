"""`RadarConfig.glasgow`: the Glasgow dataset's radar (5.8 GHz Ancortek 580AD, Yagi, Glasgow DSP)."""
import numpy as np
import pytest

from processing.dsp.signatures import signatures
from processing.synthesis.exact import synthesise
from processing.radar.waveform import C0
from rtchannel.errors import ConfigError
from rtchannel.radar import GLASGOW_SIM_BAND_M, Radar, RadarConfig

from conftest import moving_point_paths


def test_waveform_geometry_antenna_and_dsp():
    r = Radar.glasgow(height_m=1.2, distance_m=3.0)
    wf = r.waveform
    assert (wf.carrier_hz, wf.bandwidth_hz, wf.pri_s, wf.samples_per_chirp) == (5.8e9, 400e6, 1e-3, 128)
    # c / 2B = 0.3747 m bins; lambda / (4 PRI) = 0.05169 / 0.004 = 12.92 m/s unambiguous velocity
    assert wf.range_resolution == pytest.approx(C0 / 8e8, rel=1e-12)
    assert wf.v_max == pytest.approx(12.92, abs=0.01)
    assert len(r.links) == 1 and r.links[0].monostatic
    np.testing.assert_allclose(r.links[0].tx_pos, (3.0, 0.0, 1.2))
    assert r.antenna.kind == "yagi" and r.receiver.transmit_power_dbm == 18.0
    # horizontal boresight pointing at the person on the z axis: toward -x
    np.testing.assert_allclose(r.antenna.boresight_unit(r.links[0].tx_pos), (-1.0, 0.0, 0.0), atol=1e-12)
    assert r.dsp.window_chirps == 200 and r.dsp.fft_points == 800 and r.dsp.range_sum == "magnitude"
    assert (r.dsp.min_range_m, r.dsp.max_range_m) == GLASGOW_SIM_BAND_M
    # a person 1-4 m away lies inside the summed band
    assert r.dsp.min_range_m <= 1.0 and r.dsp.max_range_m >= 4.0 + 2.0


@pytest.mark.parametrize("kw", [{"distance_m": 0.5}, {"distance_m": 4.5}, {"height_m": 0.2}, {"height_m": 2.5},
                                {"distance_m": float("nan")}, {"height_m": True}, {"distance_m": "2"}])
def test_out_of_range_geometry_is_one_line_config_error(kw):
    with pytest.raises(ConfigError) as e:
        RadarConfig.glasgow(**kw)
    assert "\n" not in str(e.value) and next(iter(kw)) in str(e.value)


@pytest.mark.parametrize("r0, v", [(2.0, 1.0), (3.5, -2.5), (3.8, 4.0)])
def test_point_target_lands_in_its_range_and_velocity_bin(r0, v):
    """A point at range r(t) = r0 - v t (approaching for v > 0) over 0.6 s: p(v,t) peaks at v, the range
    distribution at r0 within one range bin.

    Velocity bin: lambda / (2 x 800 x 1 ms) = 0.0323 m/s (800-point FFT of a 200-chirp Hamming window), so a
    target held in one range bin peaks within half a bin (0.016 m/s). But the point crosses a 0.375 m range
    bin in T_r = 0.375 m / |v| (0.09-0.4 s here) against a 0.2 s window: each bin sees it only while it
    passes (range migration), so a bin's spectrum is that of a T_r-long pulse, of resolution
    lambda / (2 T_r) = lambda |v| / 0.75 m, and the magnitude sum over bins can put the peak anywhere within
    half of it: |error| <= lambda |v| / 1.5 m + 0.016 m/s (0.05 m/s at 1 m/s, 0.10 at 2.5, 0.15 at 4).
    Range: the point moves |v| x 0.6 <= 2.4 m, so the range test looks at the first window (centre 0.1 s),
    within one bin (0.375 m) of r0 - 0.1 v.
    """
    radar = RadarConfig.glasgow(receiver=None)
    wf = radar.waveform
    times = np.arange(0, 0.6, 1 / 200)
    t, iq = synthesise(moving_point_paths(r0 - v * times, times), wf)
    sig = signatures(iq, wf, radar.dsp, t0=t[0])
    # velocity axis: cropped to +-6 m/s, as the published images (ylim([-6 6]))
    dv = wf.wavelength / (2 * 800 * wf.pri_s)
    assert sig.velocity[0] >= -6.0 - 1e-9 and sig.velocity[-1] <= 6.0 + 1e-9
    assert sig.velocity[0] < -6.0 + dv and sig.velocity[-1] > 6.0 - dv
    peaks = sig.velocity[sig.p_vt.argmax(axis=0)]
    assert np.all(np.abs(peaks - v) <= wf.wavelength * abs(v) / 1.5 + dv / 2)
    r_first = r0 - v * sig.time[0]
    r_peak = sig.range[sig.range_distribution[:, 0].argmax()]
    assert abs(r_peak - r_first) <= wf.range_resolution


def test_glasgow_radar_round_trips_through_json():
    """Datasets and signature files store the radar as JSON: the Glasgow DSP (MTI cut-off in Hz, the m/s
    field at its default) must validate again to the same configuration."""
    r = RadarConfig.glasgow(height_m=0.9, distance_m=2.0)
    again = RadarConfig.model_validate(r.model_dump(mode="json"))
    assert again == r and again.dsp.mti_cutoff_hz == pytest.approx(3.75)


def test_glasgow_radar_takes_tilt_and_elevation_beamwidth():
    r = RadarConfig.glasgow(height_m=1.2, distance_m=3.0, downtilt_deg=10.0, hpbw_el_deg=40.0)
    ant = r.antenna
    assert ant.downtilt_deg == 10.0 and ant.hpbw_el_deg == 40.0
    b = ant.boresight_unit(r.links[0].tx_pos)
    assert np.degrees(np.arcsin(b[2])) == pytest.approx(-10.0, abs=1e-9)  # 10 deg below horizontal


def test_plan_draws_tilt_and_elevation_beamwidth_per_item_for_the_glasgow_kit(tmp_path):
    import yaml

    from rtchannel.dataset.plan import expand, load_plan
    from rtchannel.errors import ConfigError

    plan = {"name": "g", "motion": {"sources": [{"procedural": "fall", "variants": 3, "params": {"duration": 1.0}}]},
            "physical": {"radar": "glasgow", "angles_deg": [0.0], "downtilt_deg": [-5.0, 20.0],
                         "hpbw_el_deg": [18.0, 45.0],
                         "link_sets": [{"name": "d3", "links": [{"name": "radar1", "tx": [3.0, 0.0, 1.0]}]}]}}
    p = tmp_path / "g.yaml"
    p.write_text(yaml.safe_dump(plan))
    items = expand(load_plan(p))
    tilts = [it.radar["antenna"]["downtilt_deg"] for it in items]
    widths = [it.radar["antenna"]["hpbw_el_deg"] for it in items]
    assert all(-5.0 <= t <= 20.0 for t in tilts) and len(set(tilts)) == 3
    assert all(18.0 <= w <= 45.0 for w in widths) and len(set(widths)) == 3
    assert [it.radar["antenna"]["downtilt_deg"] for it in expand(load_plan(p))] == tilts  # seeded
    plan["physical"]["radar"] = "seed"
    p.write_text(yaml.safe_dump(plan))
    with pytest.raises((ConfigError, ValueError), match="apply to radar: glasgow"):
        load_plan(p)
