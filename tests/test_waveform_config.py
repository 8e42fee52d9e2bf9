import numpy as np
import pytest
from pydantic import ValidationError

from processing.radar.waveform import C0, Waveform
from rtchannel.radar import Link, RadarConfig, direction_angles


def test_seed_defaults_derived_quantities():
    wf = Waveform()
    lam = C0 / 24.125e9
    assert wf.v_max == pytest.approx(lam / (4 * 0.5e-3))  # 6.21 m/s, DESIGN.md
    assert wf.v_max == pytest.approx(6.2133, abs=1e-3)
    assert wf.range_resolution == pytest.approx(C0 / (2 * 250e6))  # ADC fills the chirp: c / 2B
    assert wf.velocity_resolution(64) == pytest.approx(lam / (2 * 64 * 0.5e-3))
    assert wf.fs == pytest.approx(128 / 0.5e-3)


@pytest.mark.parametrize("kwargs, field", [
    ({"pri_s": -1e-3}, "pri_s"),
    ({"carrier_hz": 0}, "carrier_hz"),
    ({"adc_rate_hz": 1e3}, "adc_rate_hz"),
    ({"chirp_duration_s": 1e-3}, "chirp_duration_s"),
    ({"samples_per_chirp": 2}, "samples_per_chirp"),
    ({"bogus": 1}, "bogus"),
])
def test_invalid_waveform_names_field(kwargs, field):
    with pytest.raises(ValidationError) as e:
        Waveform(**kwargs)
    assert field in str(e.value)


def test_adc_rate_must_cover_max_range():
    # 128 samples over the chirp -> 256 kHz; 100 m needs gamma * 2R / c = 333 kHz
    with pytest.raises(ValidationError, match="max_range_m"):
        Waveform(max_range_m=100.0)


def test_direction_angles_match_seed():
    assert direction_angles(1) == (0.0, -90.0)
    assert direction_angles(11) == (-160.0, 110.0)  # seed Fig. 6
    for k in range(1, 19):
        t1, t2 = direction_angles(k)
        assert -180 <= t1 < 180 and -180 <= t2 < 180
        assert (t1 - t2) % 360 == pytest.approx(90.0)
    with pytest.raises(ValueError):
        direction_angles(19)


def test_rotation_moves_radars_about_vertical():
    cfg = RadarConfig()
    assert cfg.links[0].tx == (3.0, 0.0, 1.1) and cfg.links[1].tx == (0.0, -3.0, 1.1)
    r = cfg.for_direction(11)
    a = np.deg2rad(-160)
    np.testing.assert_allclose(r.links[0].tx_pos, [3 * np.cos(a), 3 * np.sin(a), 1.1], atol=1e-12)
    # Radar 2 stays 90 degrees clockwise of Radar 1 (seed: theta_R1 - theta_R2 = 90)
    b = np.deg2rad(110)
    np.testing.assert_allclose(r.links[1].tx_pos, [3 * np.cos(b), 3 * np.sin(b), 1.1], atol=1e-12)


def test_links_monostatic_bistatic_and_unique_names():
    assert Link(name="a", tx=(0, 0, 1)).monostatic
    assert not Link(name="b", tx=(0, 0, 1), rx=(1, 0, 1)).monostatic
    with pytest.raises(ValidationError, match="unique"):
        RadarConfig(links=[Link(name="a", tx=(0, 0, 1)), Link(name="a", tx=(1, 0, 1))])
    with pytest.raises(ValidationError):
        Link(name="a", tx=(0, float("nan"), 1))


def test_config_file_roundtrip(tmp_path):
    p = tmp_path / "radar.yaml"
    p.write_text("waveform:\n  samples_per_chirp: 256\nlinks:\n  - {name: r1, tx: [2, 0, 1]}\n"
                 "  - {name: bi, tx: [2, 0, 1], rx: [0, 2, 1]}\n")
    cfg = RadarConfig.from_file(p)
    assert cfg.waveform.samples_per_chirp == 256 and len(cfg.links) == 2 and not cfg.links[1].monostatic
    p.write_text("waveform:\n  pri_s: -0.001\n")
    with pytest.raises(ValidationError, match="pri_s"):
        RadarConfig.from_file(p)
