"""One motion seen by several radars (the seed's directions) with the backend run once
(`rtchannel.pipeline.simulate_radars`) gives what separate `simulate` calls give."""
import numpy as np
import pytest

from rtchannel.motion.procedural import generate
from rtchannel.pipeline import simulate, simulate_radars, union_radar
from rtchannel.radar import RadarConfig


@pytest.fixture(scope="module")
def short_walk():
    return generate("walk", start=(-0.6, 0.0), distance=1.0, fps=30)


def _same(a, b, atol):
    assert a.signatures.keys() == b.signatures.keys()
    for k in a.signatures:
        sa, sb = a.signatures[k], b.signatures[k]
        np.testing.assert_allclose(sa.p_vt, sb.p_vt, rtol=0, atol=atol)
        np.testing.assert_allclose(sa.mean_velocity, sb.mean_velocity, rtol=0, atol=atol * 10)
        np.testing.assert_allclose(sa.power, sb.power, rtol=1e-6)


@pytest.mark.parametrize("backend, options", [("points", {}), ("facets", {"lod": "2k"})])
def test_shared_backend_equals_separate_runs(short_walk, backend, options):
    """Per link, the backends depend only on that link's antennas (the -50 dB path cut is per link), so the
    union of three directions' links traced together must reproduce each direction's own run; the synthesis
    and noise are the same code with the same seeds. Tolerance: float32 BVH rounding may flip a grazing
    facet (~1e-3 of the paths, ~1e-11 of the power, facets.py) -> 1e-6 of a normalised p(v,t)."""
    radars = [RadarConfig.seed(direction=d) for d in (1, 5, 12)]
    together = simulate_radars(short_walk, radars, backend, noise_seeds=[3, 4, 5], **options)
    for r, seed, res in zip(radars, (3, 4, 5), together):
        alone = simulate(short_walk, r, backend, noise_seed=seed, **options)
        _same(res, alone, 1e-6)
        assert res.config["radar"] == alone.config["radar"] and res.config["traced_with_radars"] == 3


def test_radars_of_different_polarisations_share_one_facets_run(short_walk):
    """A vertically and a horizontally polarised kit (the polarisation is an antenna property, carried per link
    through `union_radar`) traced together equal their separate runs, and differ from each other (the floor
    and wall bounces and the skin's Gamma depend on it). Tolerance as above."""
    v = RadarConfig.seed(direction=3)
    h = v.model_copy(update={"antenna": v.antenna.model_copy(update={"polarization": "H"})})
    together = simulate_radars(short_walk, [v, h], "facets", noise_seeds=[3, 3], lod="2k")  # same noise
    for r, seed, res in zip((v, h), (3, 3), together):
        _same(res, simulate(short_walk, r, "facets", noise_seed=seed, lod="2k"), 1e-6)
    pv, ph = (together[i].signatures["radar1"].p_vt for i in range(2))
    assert np.abs(np.asarray(pv) - np.asarray(ph)).max() > 1e-3


def test_union_radar_keeps_each_links_antennas_and_refuses_mixed_waveforms():
    from processing.radar.waveform import Waveform

    a, b = RadarConfig.seed(direction=1), RadarConfig.seed(direction=10)
    u = union_radar([a, b])
    assert [lk.name for lk in u.links] == ["r0__radar1", "r0__radar2", "r1__radar1", "r1__radar2"]
    assert u.links[2].tx_antenna == b.antennas(b.links[0])[0] and u.links[2].tx == b.links[0].tx
    with pytest.raises(ValueError, match="one waveform"):
        union_radar([a, RadarConfig.seed(waveform=Waveform(carrier_hz=5.8e9))])


def test_dataset_items_of_one_motion_share_the_backend_and_equal_single_runs(tmp_path):
    """A facets plan: the runner makes one task per motion (all directions and signal variants), runs it
    through `run_shared`, and every stored signature equals the item run alone (`run_item`)."""
    import yaml

    from processing.io.dataset_reader import DatasetReader
    from rtchannel.dataset.items import run_item
    from rtchannel.dataset.plan import expand, load_plan
    from rtchannel.dataset.runner import make_batches, run_plan

    data = {"name": "shared", "seed": 3, "backend": "facets", "backend_options": {"lod": "2k"},
            "motion": {"sources": [{"procedural": "fall", "variants": 1,
                                    "params": {"duration": 0.8, "pad_before": 0.2, "pad_after": 0.2}}]},
            "physical": {"directions": [1, 10]},
            "signal": {"gain_sets": [{"name": "seed"}, {"name": "j", "perturb_db": 3.0}], "snr_db": [None, 15.0]},
            "storage": {"items_per_shard": 2}}
    p = tmp_path / "plan.yaml"
    p.write_text(yaml.safe_dump(data))
    plan = load_plan(p)
    items = expand(plan)
    assert len(items) == 8 and [len(b) for b in make_batches(items, 2)] == [8]  # one motion: one task
    summary = run_plan(plan, tmp_path / "ds", workers=1, progress=False)
    assert summary.complete and not summary.failed
    reader = DatasetReader(tmp_path / "ds")
    for k, e in enumerate(reader.entries):
        assert e["params"]["traced_with_items"] == 8
        stored = reader.load(k)
        alone = run_item(next(it for it in items if it.item_id == e["item_id"]))
        for link, arrays in alone["links"].items():
            np.testing.assert_allclose(stored[link]["p_vt"], arrays["p_vt"], rtol=0, atol=1e-6)
            np.testing.assert_allclose(stored[link]["power"], arrays["power"], rtol=1e-5)
