"""Shared test helpers and the session fixtures that are expensive to make: a small simulated dataset and a
classifier trained on it, and the tiny single-radar model of the sim-to-real tests (each made once per test
session, not once per module that uses it)."""
import numpy as np
import pytest

from processing.pathset import PathSet
from processing.radar.waveform import C0


def moving_point_paths(ranges: np.ndarray, times: np.ndarray, gain: complex = 1.0) -> PathSet:
    """Persistent single path whose (bistatic half-path) range follows `ranges` [m] at `times` [s]."""
    return PathSet(times=times, delays=(2 * ranges / C0)[:, None], gains=np.full((times.size, 1), gain, complex),
                   ids=np.array([0]))


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


@pytest.fixture
def shared_data():
    """Path of a third-party data file (relative path as in the data registry); skips when absent."""
    from thirdparty import data_path

    return data_path


# 5 classes x 2 motions x 2 heights x 6 directions = 120 items on the points backend (~20 s)
TINY_PLAN = """
name: tiny
seed: 11
backend: points
motion:
  fps: 30
  sources:
    - {procedural: fall, variants: 2, params: {duration: [1.0, 1.4], pad_before: 0.2, pad_after: 0.2}}
    - {procedural: walk, variants: 2, params: {speed: [1.1, 1.4], distance: 2.0, pad_before: 0.2, pad_after: 0.2}}
    - {procedural: stand, variants: 2, params: {duration: [1.4, 1.8], pad_before: 0.2, pad_after: 0.2}}
    - {procedural: sit, variants: 2, params: {duration: [1.6, 2.0], pad_before: 0.2, pad_after: 0.2}}
    - {procedural: pick, variants: 2, params: {duration: [2.0, 2.4], pad_before: 0.2, pad_after: 0.2}}
  heights: [1.6, 1.8]
physical:
  directions: [1, 4, 7, 10, 13, 16]
signal:
  gain_sets: [{name: seed}]
storage:
  items_per_shard: 12
"""


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory):
    """The folder of TINY_PLAN's dataset, built once per session with `rtchannel.build_dataset` (what
    `rtchannel dataset --config PLAN --out DIR` runs)."""
    from rtchannel import build_dataset

    root = tmp_path_factory.mktemp("clf")
    plan = root / "plan.yaml"
    plan.write_text(TINY_PLAN)
    assert build_dataset(plan, root / "ds", workers=1).complete
    return root / "ds"


@pytest.fixture(scope="session")
def trained(tiny_dataset):
    """(reader, preprocessing, X, y, TrainResult) of a two-radar model trained on `tiny_dataset` (32 x 32 inputs)."""
    from processing.classifier import ModelConfig, PreprocessConfig, TrainConfig, train
    from processing.classifier.training import dataset_arrays
    from processing.io.dataset_reader import DatasetReader

    reader = DatasetReader(tiny_dataset)
    pre = PreprocessConfig(n_velocity=32, n_time=32)
    x, y, groups = dataset_arrays(reader, range(len(reader)), ["radar1", "radar2"], pre)
    mcfg = ModelConfig(input_size=(32, 32), padding="same")
    # batch 8 and no early stop: on 96 items BatchNorm's running statistics lag the weights for ~8 epochs
    cfg = TrainConfig(epochs=15, patience=15, batch_size=8, group_split=False, seed=3, threads=1)
    res = train(x, y, mcfg, cfg, progress=False, log=None)
    return reader, pre, x, y, res


LINE_V = np.linspace(-6.2, 6.2, 64, endpoint=False)  # velocity axis [m/s] of the synthetic line images


def velocity_line(v0: float, t: int, rng) -> np.ndarray:
    """Column-normalised p(v,t) [64, t] on LINE_V: a Gaussian line (0.3 m/s wide) at v0 plus a little noise."""
    p = np.exp(-0.5 * ((LINE_V[:, None] - v0) / 0.3) ** 2) + 1e-3 * rng.random((64, t))
    return p / p.sum(axis=0)


@pytest.fixture(scope="session")
def model_path(tmp_path_factory):
    """A 5-class, single-radar model trained on two synthetic classes: approaching (+0.5..3 m/s) = walk,
    receding (-3..-0.5 m/s) = fall. The other three classes never occur in training (32 x 32 inputs)."""
    from processing.classifier import (Classifier, ModelConfig, PreprocessConfig, TrainConfig, preprocess,
                                       save_checkpoint, train)
    from processing.labels import ACTIVITIES

    pre = PreprocessConfig(n_velocity=32, n_time=32)
    rng = np.random.default_rng(0)
    x, y = [], []
    for k in range(40):
        sign = 1 if k % 2 == 0 else -1
        t = int(rng.integers(80, 200))
        line = velocity_line(sign * rng.uniform(0.5, 3.0), t, rng)
        x.append(preprocess(line, LINE_V, np.arange(t) * 0.016, pre)[None])
        y.append(ACTIVITIES.index("walk" if sign > 0 else "fall"))
    mcfg = ModelConfig(n_classes=len(ACTIVITIES), n_branches=1, input_size=(32, 32), padding="same")
    res = train(np.stack(x), np.array(y), mcfg, TrainConfig(epochs=6, patience=6, batch_size=8, group_split=False,
                                                            seed=1, threads=1), progress=False, log=None)
    clf = Classifier(model=res.model, preprocess=pre, classes=list(ACTIVITIES), links=["radar1"])
    acc = (clf.predict(np.stack(x)) == np.array(y)).mean()
    assert acc >= 0.9, acc  # sign of a line is trivially separable; a broken training falls to ~0.5
    return save_checkpoint(tmp_path_factory.mktemp("model") / "m.pt", clf)


@pytest.fixture(scope="session")
def glasgow_dir(tmp_path_factory):
    """A folder of the twelve real Glasgow test images (skips when they are not available)."""
    from thirdparty import glasgow_folder

    return glasgow_folder(tmp_path_factory.mktemp("glasgow"))


def pytest_sessionfinish(session):
    """Under pytest-xdist, a worker hands its fuzz counts to the controller, which prints the summary."""
    if hasattr(session.config, "workeroutput"):
        from fuzz_tally import COUNTS

        session.config.workeroutput["fuzz_counts"] = dict(COUNTS)


@pytest.hookimpl(optionalhook=True)
def pytest_testnodedown(node, error):
    from fuzz_tally import COUNTS

    COUNTS.update(getattr(node, "workeroutput", {}).get("fuzz_counts", {}))


def pytest_terminal_summary(terminalreporter):
    """How many generated inputs each fuzz test accepted (tests/fuzz_tally.py)."""
    from fuzz_tally import summary

    lines = summary()
    if lines:
        terminalreporter.section("fuzz tests: accepted inputs")
        for line in lines:
            terminalreporter.write_line(line)


# Tests that take more than ~5 s on the reference machine (measured under load, `--durations`): marked `slow`
# here, in one place, so that `pytest -m "not slow"` gives a quick run while working; `make test` and CI run
# everything. A name that no longer exists fails the collection (`pytest_collection_modifyitems`).
SLOW = {
    "test_accuracy.py": ["test_calibration_measures_rows_against_a_converged_reference",
                         "test_validation_checks_named_budgets_against_the_default_on_the_same_motion",
                         "test_simulate_stores_the_budget_with_the_signature"],
    "test_ancortek.py": ["test_two_channels_interleaved_and_conjugate", "test_round_trip_reproduces_signature"],
    "test_backend_agreement.py": ["*"],
    "test_body_rcs.py": ["*"],
    "test_classifier.py": ["test_evaluate_recordings_from_dat",
                           "test_training_reaches_high_accuracy_and_reload_is_identical",
                           "test_library_training_is_the_clis_and_can_start_from_a_checkpoint",
                           "test_cli_train_evaluate_crossval",
                           "test_checkpoint_unpacking_to_more_than_the_limit_is_refused_unread"],
    "test_classifier_augment.py": ["test_cli_augment_scale_keeps_only_the_stretch_and_velocity_scale",
                                   "test_cli_train_with_augment_records_settings_and_loads",
                                   "test_cli_train_intensity_power_and_augment_noise_off"],
    "test_cli.py": ["test_render_writes_scene_png", "test_console_script_flushes_before_ending",
                    "test_simulate_writes_signature_file_and_plots"],
    "test_dataset_run.py": ["test_two_dask_workers_equal_one_worker",
                            "test_killed_run_resumes_without_duplicates_or_gaps",
                            "test_same_config_same_signatures_other_seed_differs"],
    "test_dsp_determinism.py": ["test_whole_chain_same_bytes_with_one_and_two_blas_threads"],
    "test_facet_speed.py": ["test_indexed_gains_equal_the_gathered_route_bitwise"],
    "test_fuzz_inputs.py": ["test_bvh_fuzz", "test_c3d_semantic_fuzz", "test_c3d_byte_fuzz", "test_scene_xml_fuzz"],
    "test_fuzz_phase2.py": ["test_plan_structure_fuzz"],
    "test_glasgow_preset.py": ["test_every_shipped_walk_take_builds_a_back_and_forth_clip"],
    "test_plan_yaml.py": ["test_expanded_size_limit_is_exact"],
    "test_shared_directions.py": ["*"],
    "test_sionna_antennas.py": ["*"],
    "test_sionna_backend.py": ["*"],
    "test_startup_imports.py": ["test_points_figures_use_matplotlib_without_pyplot",
                                "test_facets_simulate_builds_the_scene_once_without_sionna"],
    "test_wall_images.py": ["test_coarse_image_lod_keeps_image_power_and_direct_paths",
                            "test_coarse_image_lod_keeps_coherent_image_power_with_defaults"],
}


def pytest_collection_modifyitems(config, items):
    """Mark the tests named in SLOW (a file's "*": all of its tests) `slow`; a name that matches no collected
    test of a collected file is an error, so the list cannot rot."""
    seen = set()
    for item in items:
        file, name = item.path.name, getattr(item, "originalname", item.name)
        names = SLOW.get(file, ())
        if "*" in names or name in names:
            item.add_marker(pytest.mark.slow)
            seen.add((file, "*" if "*" in names else name))
    files = {item.path.name for item in items}
    stale = [f"{f}::{n}" for f, names in SLOW.items() if f in files for n in names if (f, n) not in seen]
    narrowed = config.getoption("-k") or config.getoption("-m") or any("::" in str(a) for a in config.args)
    if stale and not narrowed:
        raise pytest.UsageError(f"tests/conftest.py SLOW names tests that do not exist: {', '.join(stale)}")
