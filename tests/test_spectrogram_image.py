"""Spectrogram images: MATLAB jet, Glasgow layout and names, reader/writer round trips, errors, real images.

Quantisation bound used throughout: N = 256 colours over a 40 dB span are bins of 40/256 = 0.156 dB;
the writer puts a value in its bin and the reader returns the bin centre, so an exact colour carries
|error| <= DB_STEP / 2 = 0.078 dB (8-bit storage does not add to it: neighbouring jet(256) entries
differ by 255/64 ~ 4 levels in one channel, so every entry is a distinct 8-bit colour).
"""
import csv
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from processing.realdata.colormaps import colormap_inverse, matlab_jet
from processing.dsp.signatures import DSPConfig, signatures
from processing.realdata.spectrogram_image import (ImageLayout, SpectrogramImageError, detect_glasgow_duration,
                                          glasgow_layout, load_rgb, parse_glasgow_name, read_glasgow_image,
                                          read_spectrogram_image, remap_matrix, cell_edges)
from processing.realdata.spectrogram_image_writer import render_box, render_image, write_spectrogram_image
from processing.synthesis.exact import synthesise
from processing.radar.waveform import Waveform

from conftest import moving_point_paths
from thirdparty import GLASGOW_INDEX, GLASGOW_TEST_IMAGES, data_path

REAL = GLASGOW_TEST_IMAGES  # registry paths; each test gets its file with data_path (skips without the data)
SPAN, N = 40.0, 256
DB_STEP = SPAN / N
EPS = 1e-9


def _ridges(v, t):
    """Power [V, T] of three Gaussian ridges (0, -10 and -30 dB peaks) and its dB relative to its max."""
    vv, tt = v[:, None], t[None, :]
    p = (np.exp(-0.5 * ((vv - 1.5 * np.sin(2 * np.pi * tt / 2.5)) / 0.25) ** 2)
         + 0.1 * np.exp(-0.5 * ((vv + 2.0 - 0.4 * tt) / 0.4) ** 2)
         + 1e-3 * np.exp(-0.5 * ((vv - 4.0) / 0.2) ** 2))
    with np.errstate(divide="ignore"):
        return p, 10 * np.log10(p / p.max())


def _box(img, lay):
    return img[lay.box_top:lay.box_bottom + 1, lay.box_left:lay.box_right + 1]


# ---- colormap -------------------------------------------------------------------------------------
def test_matlab_jet_matches_matlab():
    # MATLAB documents jet(64) as running from [0 0 0.5625] to [0.5 0 0]; jet(256) starts at 33/64.
    j64 = matlab_jet(64)
    np.testing.assert_array_equal(j64[0], [0, 0, 0.5625])
    np.testing.assert_array_equal(j64[-1], [0.5, 0, 0])
    np.testing.assert_array_equal(matlab_jet(256)[0], [0, 0, 33 / 64])
    # every entry of jet(256) is a distinct 8-bit colour (the reader could not tell them apart otherwise)
    assert len({tuple(c) for c in colormap_inverse("matlab_jet", 256).entries}) == 256


@pytest.mark.parametrize("path", REAL, ids=lambda p: Path(p).stem)
def test_real_images_use_exactly_matlab_jet(path):
    path = data_path(path)
    # Every box pixel is an exact floor(255 jet(256)) colour except the tick marks: 4 interior time
    # ticks x 3 px at top and bottom (24) + 5 interior velocity ticks x 3 px left and right (30) = 54.
    rgb, _ = load_rgb(path)
    lay = glasgow_layout(detect_glasgow_duration(rgb))
    _, dist = colormap_inverse("matlab_jet", 256).invert(_box(rgb, lay))
    assert (dist > 0).sum() == 54 and (dist[dist > 0] > 6).all()


# ---- layout and names -----------------------------------------------------------------------------
@pytest.mark.parametrize("duration", [5.0, 10.0])
def test_glasgow_layout_box_is_inside_the_frame(duration):
    # The frame pixels found on the real images bound the box; the axis limits sit on the frame.
    lay = glasgow_layout(duration)
    assert (lay.box_top, lay.box_bottom, lay.box_left) == (37, 353, 65)
    assert lay.box_right == {5.0: 447, 10.0: 441}[duration]
    rows, cols = lay.box_shape
    np.testing.assert_allclose(lay.velocity_top + 0.5 * (lay.velocity_top - lay.velocity_bottom) / rows, 6.0)
    np.testing.assert_allclose(lay.time_right + 0.5 * (lay.time_right - lay.time_left) / cols, duration)
    assert lay.row_velocity()[(rows - 1) // 2] == pytest.approx(0.0, abs=1e-12)  # row 195: the 0 m/s tick


def test_layout_validation():
    good = glasgow_layout(5.0).model_dump()
    for bad in ({"box_right": 600}, {"box_top": 360}, {"velocity_top": float("nan")}, {"time_right": 0.0},
                {"unknown_field": 1}, {"frame_rgb": (0, 0, 300)}):
        with pytest.raises(ValueError):
            ImageLayout(**{**good, **bad})


def test_all_360_glasgow_names_parse_and_agree_with_index():
    project = {"walk": "walk", "sit_down": "sit", "stand_up": "stand", "pick_up": "pick", "drink": "drink",
               "fall": "fall"}
    with open(GLASGOW_INDEX, newline="") as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 360
    counts = {}
    for row in rows:
        lab = parse_glasgow_name(Path(row["path"]).name)
        assert lab.activity == project[row["activity"]]
        assert (lab.subject, lab.repetition, lab.activity_digit) == (int(row["subject"][1:]), int(row["rep"]),
                                                                     int(row["activity_digit"]))
        counts[lab.activity] = counts.get(lab.activity, 0) + 1
    assert counts == dict.fromkeys(project.values(), 60)


@pytest.mark.parametrize("name, words", [("7P36A07R01.png", "unknown activity digit 7"),
                                         ("1P36A02R01.png", "disagrees"), ("walk_01.png", "not a Glasgow")])
def test_bad_glasgow_names(name, words):
    with pytest.raises(SpectrogramImageError) as e:
        parse_glasgow_name(name)
    assert name in str(e.value) and words in str(e.value) and "\n" not in str(e.value)


# ---- writer placement and round trips -------------------------------------------------------------
@pytest.mark.parametrize("duration", [5.0, 10.0])
def test_writer_places_the_box_pixel_exactly(duration):
    lay = glasgow_layout(duration)
    v, t = np.sort(lay.row_velocity()), lay.column_time()
    _, db = _ridges(v, t)
    img = render_image(v, t, lay, db=db, title="x")
    box = render_box(v, t, db, lay)
    np.testing.assert_array_equal(_box(img, lay), box)
    # orientation: a ramp brightest at the highest velocity and the latest time lands top right
    ramp = -SPAN / 2 * ((v[-1] - v) / (v[-1] - v[0]))[:, None] - SPAN / 2 * ((t[-1] - t) / (t[-1] - t[0]))[None, :]
    corner = render_box(v, t, ramp, lay)
    entries = colormap_inverse("matlab_jet").entries
    np.testing.assert_array_equal(corner[0, -1], entries[-1])
    np.testing.assert_array_equal(corner[-1, 0], entries[0])
    # the frame on the pixels just outside the box, as in the real images, so the duration is detected
    assert (img[lay.box_top - 1, lay.box_left:lay.box_right + 1] == (38, 38, 38)).all()
    assert (img[lay.box_top:lay.box_bottom + 1, lay.box_right + 1] == (38, 38, 38)).all()
    assert detect_glasgow_duration(img) == duration
    # on the pixel grid, linear interpolation between pixel centres is the identity: same pixels
    np.testing.assert_array_equal(render_box(v, t, db, lay, interpolation="linear"), box)


def test_round_trip_on_the_pixel_grid(tmp_path):
    lay = glasgow_layout(5.0)
    v, t = np.sort(lay.row_velocity()), lay.column_time()
    p, db = _ridges(v, t)
    path = write_spectrogram_image(tmp_path / "ridges.png", v, t, lay, power=p)
    r = read_spectrogram_image(path, lay)
    np.testing.assert_array_equal(r.velocity, v)
    np.testing.assert_array_equal(r.time, t)
    above = db >= -SPAN + DB_STEP  # true value above the floor bin
    assert np.abs(r.db - db)[above].max() <= DB_STEP / 2 + EPS
    assert (r.db[~above] == r.floor_db).all() and r.off_map_fraction == 0.0

    # Mean velocity: each power is off by a factor within 10^(+-DB_STEP/20), i.e. w_i (1 + e_i), |e_i| <=
    # e = 10^(DB_STEP/20) - 1 = 1.8 %; as sum (v_i - m) p_i = 0, the mean moves by at most
    # e * sum |v_i - m| p_i / (1 - e'), with 1 - e' = 10^(-DB_STEP/20) the smallest denominator.
    ptrue = np.where(above, p, 0.0)
    ptrue = ptrue / ptrue.sum(axis=0)
    m = v @ ptrue
    mad = (np.abs(v[:, None] - m[None, :]) * ptrue).sum(axis=0)
    e = 10 ** (DB_STEP / 20) - 1
    bound = e * mad / 10 ** (-DB_STEP / 20)
    assert (np.abs(r.signature.mean_velocity - m) <= bound + EPS).all()
    np.testing.assert_allclose(r.signature.p_vt.sum(axis=0), 1.0)


def test_round_trip_from_a_coarse_grid():
    # A simulator-like grid (0.19 m/s, 32 ms cells) drawn "nearest": every pixel shows the cell holding
    # its centre, so reading back gives that cell's dB within the quantisation; a box one pixel off
    # would put the pixels along each cell edge in the neighbouring cell (steps of several dB here).
    lay = glasgow_layout(5.0)
    v, t = np.linspace(-5.9, 5.9, 61), np.arange(0.016, 4.9, 0.032)
    _, db = _ridges(v, t)
    r = read_spectrogram_image(render_image(v, t, lay, db=db, decorations=False), lay)
    v_edges, t_edges = cell_edges(v), cell_edges(t)  # midpoints; half a spacing beyond the ends
    iv = np.searchsorted(v_edges, r.velocity) - 1
    it = np.searchsorted(t_edges, r.time) - 1
    assert iv.min() == 0 and iv.max() == v.size - 1  # the grid covers the box's velocities ...
    outside = it >= t.size  # ... but not its last 0.1 s: shown below the scale
    expect = np.maximum(db[iv][:, np.minimum(it, t.size - 1)], r.floor_db)
    expect[:, outside] = r.floor_db
    assert np.abs(r.db - expect).max() <= DB_STEP / 2 + EPS


@pytest.mark.parametrize("cmap", ["viridis", "gray", "jet"])
def test_round_trip_with_a_matplotlib_colormap(cmap):
    # 8-bit storage makes runs of L neighbouring entries identical (gray, viridis: L = 2; matplotlib's
    # jet: 4); such a colour reads as the run's middle, so the bound widens to L * DB_STEP / 2.
    lay = glasgow_layout(5.0).model_copy(update={"colormap": cmap, "frame_rgb": None})
    v, t = np.sort(lay.row_velocity()), lay.column_time()
    _, db = _ridges(v, t)
    r = read_spectrogram_image(render_image(v, t, lay, db=db), lay)
    run = colormap_inverse(cmap).max_run
    above = db >= -SPAN + run * DB_STEP
    assert np.abs(r.db - db)[above].max() <= run * DB_STEP / 2 + EPS


def test_simulated_signature_through_the_real_layout():
    """A point approaching at v0: DSP signature -> Glasgow-layout image -> reader -> mean velocity ~ v0.

    Per column, the read mean differs from v0 by at most: |DSP mean - v0|; + half a pixel (dp/2: where the
    pixels of a cell sit vs its centre); + the cell weights' error: a cell of width dv gets dv/dp +- 1
    pixels (relative error r = dp/dv) and a colour quantisation factor, together e = (1 + r) 10^(q/20) - 1,
    moving the mean by e * MAD / ((1 - r) 10^(-q/20)); + the mass D the image cannot show (below the
    -40 dB floor, or outside +-6 m/s), which moves the mean by at most sum_D p |v - m| / (1 - D).
    """
    wf = Waveform()
    v0 = 1.5
    times = np.arange(0, 1.2, 1 / 60)
    t0, iq = synthesise(moving_point_paths(5.0 - v0 * times, times), wf)
    sig = signatures(iq, wf, DSPConfig(doppler_window="hann"), t0=t0[0])
    lay = glasgow_layout(5.0)
    r = read_spectrogram_image(render_image(sig.velocity, sig.time, lay, power=sig.p_vt * sig.power), lay)
    s = r.signature
    edges = np.concatenate([[sig.time[0] - 0.5 * (sig.time[1] - sig.time[0])], (sig.time[1:] + sig.time[:-1]) / 2,
                            [sig.time[-1] + 0.5 * (sig.time[1] - sig.time[0])]])
    k = np.searchsorted(edges, r.time, side="right") - 1
    inside = (k >= 0) & (k < sig.time.size)
    assert (s.valid == inside).all()  # columns beyond the recording are empty, the others are not

    dp = lay.velocity_edges()[1] - lay.velocity_edges()[0]
    rel = dp / (sig.velocity[1] - sig.velocity[0])
    e = (1 + rel) * 10 ** (DB_STEP / 20) - 1
    p = sig.p_vt[:, k[inside]]
    m = sig.mean_velocity[k[inside]]
    dev = np.abs(sig.velocity[:, None] - m[None, :])
    power = sig.p_vt * sig.power
    shown = (10 * np.log10(np.maximum(power / power.max(), 1e-300)) >= -SPAN + DB_STEP)[:, k[inside]]
    shown &= (np.abs(sig.velocity) < lay.velocity_top)[:, None]
    dropped = np.where(shown, 0.0, p)
    bound = (np.abs(m - v0) + dp / 2 + e * (dev * p).sum(axis=0) / ((1 - rel) * 10 ** (-DB_STEP / 20))
             + (dev * dropped).sum(axis=0) / (1 - dropped.sum(axis=0)))
    assert (np.abs(s.mean_velocity[inside] - v0) <= bound).all()
    assert (s.mean_velocity[~inside] == 0).all()


def test_resampling_conserves_power_and_rejects_grids_outside(tmp_path):
    lay = glasgow_layout(5.0)
    src = lay.velocity_edges()
    dst = np.linspace(src[0], src[-1], 41)[:-1] + (src[-1] - src[0]) / 80  # cells tiling the extent exactly
    w = remap_matrix(src, dst)
    np.testing.assert_allclose(w.sum(axis=1), 1.0)
    np.testing.assert_allclose((w * np.diff(np.linspace(src[0], src[-1], 41))[:, None]).sum(axis=0), np.diff(src))
    v, t = np.sort(lay.row_velocity()), lay.column_time()
    p, _ = _ridges(v, t)
    path = write_spectrogram_image(tmp_path / "r.png", v, t, lay, power=p)
    r = read_spectrogram_image(path, lay, velocity=dst, time=np.arange(0.05, 4.95, 0.1))
    assert r.db.shape == (40, 49) and r.signature.p_vt.shape == (40, 49)
    np.testing.assert_allclose(r.signature.p_vt.sum(axis=0), 1.0)
    with pytest.raises(SpectrogramImageError, match="r.png.*outside"):
        read_spectrogram_image(path, lay, velocity=np.linspace(-8, 8, 64))


# ---- errors ---------------------------------------------------------------------------------------
def _one_line_naming(excinfo, path):
    msg = str(excinfo.value)
    return str(path) in msg and "\n" not in msg


def _written(tmp_path):
    lay = glasgow_layout(5.0)
    v, t = np.sort(lay.row_velocity()), lay.column_time()
    p, _ = _ridges(v, t)
    return write_spectrogram_image(tmp_path / "ok.png", v, t, lay, power=p), lay


def test_wrong_size_image(tmp_path):
    path = tmp_path / "small.png"
    Image.new("RGB", (100, 80)).save(path)
    with pytest.raises(SpectrogramImageError, match="100x80") as e:
        read_spectrogram_image(path, glasgow_layout(5.0))
    assert _one_line_naming(e, path)
    with pytest.raises(SpectrogramImageError, match="no Glasgow plot frame") as e:
        read_glasgow_image(path)
    assert _one_line_naming(e, path)


def test_not_an_image(tmp_path):
    path = tmp_path / "text.png"
    path.write_text("not a png\n")
    with pytest.raises(SpectrogramImageError, match="not a readable image") as e:
        read_spectrogram_image(path, glasgow_layout(5.0))
    assert _one_line_naming(e, path)
    with pytest.raises(SpectrogramImageError) as e:
        read_spectrogram_image(tmp_path / "missing.png", glasgow_layout(5.0))
    assert _one_line_naming(e, tmp_path / "missing.png")


@pytest.mark.parametrize("cmap, words", [("no_such_map", "unknown colormap"), ("twilight", "not invertible")])
def test_unknown_or_ambiguous_colormap(tmp_path, cmap, words):
    path, lay = _written(tmp_path)
    with pytest.raises(SpectrogramImageError, match=words) as e:
        read_spectrogram_image(path, lay.model_copy(update={"colormap": cmap}))
    assert _one_line_naming(e, path)


def test_garbage_colours_inside_the_box(tmp_path):
    path, lay = _written(tmp_path)
    rgb = np.array(Image.open(path).convert("RGB"))
    # 60 x 60 random colours = 3.0 % of the box; at most ~1 % of random colours fall within 6 levels
    # of the jet polyline (its length ~1300 levels x a 6-level tube is < 0.1 % of the RGB cube)
    rgb[100:160, 200:260] = np.random.default_rng(7).integers(0, 256, (60, 60, 3), dtype=np.uint8)
    bad = tmp_path / "garbage.png"
    Image.fromarray(rgb).save(bad)
    with pytest.raises(SpectrogramImageError, match="off the matlab_jet colormap") as e:
        read_spectrogram_image(bad, lay)
    assert _one_line_naming(e, bad)


def test_writer_errors_name_the_file(tmp_path):
    lay = glasgow_layout(5.0)
    v, t = np.linspace(-5, 5, 10), np.linspace(0, 4, 20)
    with pytest.raises(SpectrogramImageError, match="NaN") as e:
        write_spectrogram_image(tmp_path / "nan.png", v, t, lay, db=np.full((10, 20), np.nan))
    assert _one_line_naming(e, tmp_path / "nan.png")
    with pytest.raises(SpectrogramImageError, match="ascending") as e:
        write_spectrogram_image(tmp_path / "desc.png", v[::-1], t, lay, db=np.zeros((10, 20)))


# ---- real images ----------------------------------------------------------------------------------
@pytest.mark.parametrize("path", REAL, ids=lambda p: Path(p).stem)
def test_real_glasgow_images(path):
    path = data_path(path)
    lab = parse_glasgow_name(path.name)
    r = read_glasgow_image(path)
    # walks are 10 s; so is the one sit-down 2P36A02R01 (detected from its frame, not its label)
    # (the last pixel centre is 1.5 px before the axis end: 0.04 s at 10 s, 0.02 s at 5 s)
    assert r.time[-1] == pytest.approx(10.0 if lab.activity == "walk" or lab.stem == "2P36A02R01" else 5.0, abs=0.05)
    lay = glasgow_layout(10.0 if r.time[-1] > 6 else 5.0)
    assert r.off_map_fraction * np.prod(lay.box_shape) == pytest.approx(54)  # the tick marks
    s = r.signature
    assert np.isfinite(r.db).all() and np.isfinite(s.p_vt).all() and np.isfinite(s.mean_velocity).all()
    sums = s.p_vt.sum(axis=0)
    np.testing.assert_allclose(sums[s.valid], 1.0)
    assert (sums[~s.valid] == 0).all() and s.valid.mean() > 0.3
    assert (np.abs(s.velocity) < 6.0).all() and (np.abs(s.mean_velocity) < 6.0).all()
    # The scale's top is the strongest STFT cell; the drawing samples ~1 in 2.6 STFT frames, so that cell
    # may be skipped, but its neighbours (95 % overlap) are drawn: 322 of the 360 images show the top
    # colour, all show a pixel within 1.02 dB of it.
    assert -2.0 < r.db.max() <= -DB_STEP / 2
    if lab.activity == "walk":
        # walking toward and then away from the radar: the torso ridge is at about +-1 m/s (60 walks:
        # the largest column mean is >= 0.96 m/s and the smallest <= -0.88 m/s), so both signs clearly
        assert s.mean_velocity.max() > 0.5 and s.mean_velocity.min() < -0.5


def test_floor_option_on_a_real_fall():
    # This fall is over after ~2 s and, unlike 6P36A06R01, has no interference lines: the later columns
    # hold only floor pixels. "zero" makes them empty (p = 0, mean 0, invalid); "keep" gives every floor
    # pixel the same power, so those columns are uniform: p = 1/V.
    path = data_path("realdata/glasgow848/1Dataset/6P46A06R01.png")
    zero, keep = read_glasgow_image(path), read_glasgow_image(path, floor="keep")
    empty = ~zero.signature.valid
    assert empty.sum() > 0.3 * empty.size and keep.signature.valid.all()
    np.testing.assert_allclose(keep.signature.p_vt[:, empty], 1.0 / keep.velocity.size)
    np.testing.assert_array_equal(zero.db, keep.db)
    assert (zero.signature.mean_velocity[empty] == 0).all()
