"""Ancortek `.dat` recordings: a simulated signal written in the format and read back gives the same signature."""
import numpy as np
import pytest

from processing.realdata.ancortek import AncortekFormatError, read_dat, write_dat
from processing.dsp.signatures import signatures
from processing.radar.receiver import noise_power_per_sample
from rtchannel.motion.procedural import generate
from rtchannel.radar import RadarConfig
from rtchannel.pipeline import simulate


@pytest.fixture(scope="module")
def simulated():
    radar = RadarConfig()
    motion = generate("walk", duration=1.2, start=(-0.8, 0.0), fps=60.0, pad_before=0.2, pad_after=0.2)
    res = simulate(motion, radar, backend="points", keep_iq=True)
    return radar, res


def test_round_trip_reproduces_signature(simulated, tmp_path):
    radar, res = simulated
    wf, dsp = radar.waveform, radar.dsp
    link = res.links["radar1"]
    path = write_dat(tmp_path / "walk_radar1.dat", link.iq, wf)
    rec = read_dat(path)
    assert rec.header["n_sweeps"] == link.iq.shape[0]
    # header in GHz/ms/MHz text must come back to the same waveform (relative 1e-12: repr round trip)
    assert rec.waveform.carrier_hz == pytest.approx(wf.carrier_hz, rel=1e-12)
    assert rec.waveform.pri_s == pytest.approx(wf.pri_s, rel=1e-12)
    assert rec.waveform.bandwidth_hz == pytest.approx(wf.bandwidth_hz, rel=1e-12)
    # 9 significant digits reproduce float32 IQ exactly
    np.testing.assert_array_equal(rec.iq[0], link.iq.astype(np.complex64))
    # the simulation knew its receiver's noise level: give the DSP the same (a real recording does not)
    sig = signatures(rec.iq[0], rec.waveform, dsp, t0=float(link.chirp_times[0]),
                     noise_power=noise_power_per_sample(radar.receiver, wf.fs))
    ref = link.signature
    np.testing.assert_allclose(sig.velocity, ref.velocity, rtol=1e-12)
    np.testing.assert_allclose(sig.time, ref.time, rtol=1e-12)
    # same IQ through the same DSP: p(v,t) equal to float64 rounding of the float32 input
    np.testing.assert_allclose(sig.p_vt, ref.p_vt, atol=1e-9)
    np.testing.assert_allclose(sig.mean_velocity, ref.mean_velocity, atol=1e-9)
    assert sig.p_vt.shape[1] > 30 and np.abs(ref.mean_velocity).max() > 0.5  # a real walk, not silence


def test_two_channels_interleaved_and_conjugate(simulated, tmp_path):
    radar, res = simulated
    iq1, iq2 = res.links["radar1"].iq, res.links["radar2"].iq
    path = write_dat(tmp_path / "both.dat", [iq1, iq2], radar.waveform)
    rec = read_dat(path, n_channels=2)
    np.testing.assert_array_equal(rec.iq[0], iq1)
    np.testing.assert_array_equal(rec.iq[1], iq2)
    conj = read_dat(tmp_path / "both.dat", n_channels=2, conjugate=True)
    np.testing.assert_array_equal(conj.iq[1], iq2.conj())


def test_tolerant_syntax_and_hz_header(tmp_path):
    # Hz/Hz header, 'j' and spaces, blank lines, a bare real: all accepted
    text = "24125000000\n0.5\n8\n250000000\n\n1+2i\n -0.5 - 0.25j\n3\n1e-3+1E-3i\n" + "0\n" * 4
    p = tmp_path / "x.dat"
    p.write_text(text)
    rec = read_dat(p)
    np.testing.assert_allclose(rec.iq[0][0, :4], [1 + 2j, -0.5 - 0.25j, 3, 1e-3 + 1e-3j], rtol=1e-7)
    assert rec.waveform.carrier_hz == 24.125e9 and rec.waveform.bandwidth_hz == 250e6


@pytest.mark.parametrize("text, match", [
    ("24.125\n0.5\n", "header needs 4 lines"),
    ("24.125\n0.5\nabc\n250\n1+1i\n", "line 3: samples per sweep is not a number"),
    ("24.125\n0.5\n2\n250\n1+1i\n1+zi\n", "line 6: not a complex sample"),
    ("24.125\n0.5\n2\n250\n1+1i\n1+1i\n1+1i\n", "truncated: 3 samples"),
    ("24.125\n0.5\n2.5\n250\n1+1i\n", "implausible header"),
    ("24.125\n0.5\n2\n250\n1+1i\n1+1i\n", "not describe a valid FMCW waveform"),
])
def test_malformed_files_raise_clear_errors(tmp_path, text, match):
    p = tmp_path / "bad.dat"
    p.write_text(text)
    with pytest.raises(AncortekFormatError, match=match):
        read_dat(p)


def test_partial_last_sweep_can_be_dropped(tmp_path):
    p = tmp_path / "part.dat"
    p.write_text("24.125\n0.5\n8\n250\n" + "1+1i\n" * 11)
    rec = read_dat(p, allow_partial=True)
    assert rec.iq[0].shape == (1, 8) and rec.header["dropped_samples"] == 3


@pytest.mark.parametrize("sample, line", [("nan", 7), ("1e308+1i", 7), ("inf-2j", 7), ("1+nanj", 7), ("-1e13", 7)])
def test_non_finite_or_absurd_samples_name_the_line(tmp_path, sample, line):
    # a finite-but-huge sample would overflow |FFT|^2 in float32: refused like nan (limit 1e12)
    p = tmp_path / "bad.dat"
    p.write_text("24.125\n0.5\n2\n250\n1+1i\n1-1i\n" + sample + "\n0\n")
    with pytest.raises(AncortekFormatError, match=rf"bad\.dat: line {line}: sample .* not finite or beyond"):
        read_dat(p)


@pytest.mark.parametrize("header, match", [
    ("inf\n0.5\n8\n250\n", "line 1: implausible header: carrier"),
    ("24.125\nnan\n8\n250\n", "line 2: implausible header: sweep time"),
    ("24.125\n0.5\n1e9\n250\n", "line 3: implausible header: samples per sweep"),
    ("24.125\n0.5\n8\n1e300\n", "line 4: implausible header: bandwidth"),
])
def test_header_bounds(tmp_path, header, match):
    p = tmp_path / "h.dat"
    p.write_text(header + "1+1i\n" * 8)
    with pytest.raises(AncortekFormatError, match=match):
        read_dat(p)


def test_line_endings_and_channel_argument(tmp_path):
    body = ["24.125", "0.5", "8", "250"] + [f"{k}+{k}i" for k in range(16)]
    for name, sep in (("crlf.dat", "\r\n"), ("cr.dat", "\r"), ("lf.dat", "\n")):
        p = tmp_path / name
        p.write_bytes(sep.join(body).encode() + sep.encode())
        rec = read_dat(p)
        np.testing.assert_array_equal(rec.iq[0].ravel(), np.arange(16) * (1 + 1j))
    with pytest.raises(AncortekFormatError, match="n_channels must be an integer 1..8"):
        read_dat(tmp_path / "lf.dat", n_channels=0)


def test_binary_garbage_is_a_format_error(tmp_path):
    p = tmp_path / "garbage.dat"
    p.write_bytes(b"24.125\n0.5\n2\n250\n\xff\xfe\x00\x01\n")
    with pytest.raises(AncortekFormatError, match=r"line 5: not a complex sample"):
        read_dat(p)
