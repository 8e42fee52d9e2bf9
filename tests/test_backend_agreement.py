"""`facets` against the `sionna` reference on the same walk, walls off (free space), diffuse skin.

Both use Sionna RT's diffuse model for the default skin (Lambertian, S = 0.5, Gabriel dry skin); Sionna's
specular term is off: monostatically it finds no body specular path (see test_sionna_backend) and only
thins the diffuse sampling. The facets' physical-optics term (on by default) is off here for the same reason:
this compares the two evaluations of one diffuse model.

Both diffuse fields are speckle: facets gives each facet a fixed random phase (seeded), Sionna's rays hit
random points of the facets (exact path lengths). Two speckle realisations differ in their mean velocity by
chance (facets seeds 0..7 against the one Sionna run: radar 1 RMSE 0.117..0.193 m/s, radar 2 0.065..0.083),
so the mean velocity is compared as the average over facets seeds 0..3 (the expectation over the surface
phase; measured 0.118 and 0.056 m/s). The power per frame does not depend on the phases.
"""
import numpy as np
import pytest

from processing.radar.antenna import Isotropic
from rtchannel.backends.facets import facet_paths
from rtchannel.backends.sionna_rt import sionna_paths
from rtchannel.motion.procedural import generate
from rtchannel.radar import Link, RadarConfig
from rtchannel.pipeline import process_paths


@pytest.fixture(scope="module")
def walk_paths():
    m = generate("walk", duration=1.5, start=(-1.0, 0.0), pad_before=0.2, pad_after=0.2)
    # unit-gain antennas on both: this compares the scattering models (the horns multiply both alike)
    radar = RadarConfig(links=[Link(name="r1", tx=(3.0, 0.0, 1.1)), Link(name="r2", tx=(0.0, -3.0, 1.1))],
                        antenna=Isotropic())
    pf = [facet_paths(m, radar, scene="free_space", lod="2k", walls=False, trace_fps=20, po=False, seed=seed)
          for seed in range(4)]
    ps = sionna_paths(m, radar, scene="free_space", lod="2k", trace_fps=20, samples_per_src=200_000,
                      specular=False)
    return radar, pf, ps


def test_total_body_power_within_2db(walk_paths):
    _, pfs, ps = walk_paths
    pf = pfs[0]
    for name in pf:
        a, b = pf[name], ps[name]
        idx = np.searchsorted(a.times, b.times - 1e-9)
        np.testing.assert_allclose(a.times[idx], b.times, atol=1e-9)  # the same frames
        pa = np.sum(np.abs(a.gains[idx]) ** 2, axis=1)
        pb = np.sum(np.abs(b.gains) ** 2, axis=1)
        db = 10 * np.log10(pb / pa)
        # The 2 dB per frame (measured: within 0.1 dB, the same diffuse model on the same mesh).
        assert np.all(np.abs(db) < 2.0), f"{name}: {db}"


def test_walk_mean_velocity_rmse(walk_paths):
    radar, pfs, ps = walk_paths
    ras, rb = [process_paths(pf, radar) for pf in pfs], process_paths(ps, radar)
    for name in rb:
        sas, sb = [ra[name].signature for ra in ras], rb[name].signature
        n = min(len(sas[0].time), len(sb.time))  # sionna's last traced frame may end one window earlier
        np.testing.assert_allclose(sas[0].time[:n], sb.time[:n])
        ok = np.all([sa.valid[:n] for sa in sas], axis=0) & sb.valid[:n]
        assert ok.sum() > 0.9 * n
        mean_v = np.mean([sa.mean_velocity[:n] for sa in sas], axis=0)  # expectation over the surface phase
        rmse = np.sqrt(np.mean((mean_v[ok] - sb.mean_velocity[:n][ok]) ** 2))
        # The 0.15 m/s (measured 0.118 radar 1, 0.056 radar 2 at 2e5 rays: Sionna's one speckle
        # realisation and its Monte-Carlo sampling against every facet); a sign or Doppler-scale error gives
        # ~1 m/s.
        assert rmse < 0.15, f"{name}: RMSE {rmse:.3f} m/s"
        # The walk is really seen moving (radar 2 sees it from the side: peak 0.28 m/s after the average).
        assert np.max(np.abs(mean_v[ok])) > 0.2
