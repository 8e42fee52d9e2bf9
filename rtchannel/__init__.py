"""rtchannel: human motion -> skinned body -> scattering paths -> FMCW MIMO radar signatures.

The public API (few nouns, one `simulate`)::

    from rtchannel import Motion, Radar, Scene, simulate

    motion = Motion.procedural("walk", height=1.75, seed=0)     # or Motion.from_file("take.bvh")
    radar = Radar.seed(direction=1)                               # the seed's 2x2 MIMO radar
    result = simulate(motion, radar, backend="facets", scene=Scene.room())
    result.signatures["radar1"].p_vt                              # p(v, t), eq. 7
    channel = trace(motion, radar, backend="facets")              # the path sets per link, then
    result = synthesise(channel)                                  # raw IQ and signatures (= simulate)
    result.save("out/signature.h5"); result.save_figures("out/")  # SimulationResult.load reads it back
    fig = result.plot(ax=None, kind="pvt")                        # draw (onto your Axes with ax=)
    result = synthesise(channel, dsp=DSPConfig(window_chirps=128), keep_iq=True)   # other DSP, same channel
    sigs = process(result.iq, radar)                              # stored raw IQ -> signatures
    results = simulate_radars(motion, [Radar.seed(direction=d) for d in range(1, 19)], backend="facets")
                                                                  # 18 directions, body traced once per frame

Names are imported on first use, so `import rtchannel` stays cheap (and works before the
dependencies are installed, which the Makefile's LLVM check relies on).
"""
__version__ = "0.1.0"

_EXPORTS = {
    # motion, radar, scene
    "Motion": ("rtchannel.motion.pose", "Motion"),
    "Rig": ("rtchannel.motion.pose", "Rig"),
    "place_take": ("rtchannel.motion.compose", "place_take"),
    "BodyShape": ("rtchannel.body.shape", "BodyShape"),
    "draw_body_shape": ("rtchannel.body.shape", "draw_body_shape"),
    "reshape_motion": ("rtchannel.body.shape", "reshape_motion"),
    "Radar": ("rtchannel.radar", "RadarConfig"),
    "Link": ("rtchannel.radar", "Link"),
    "Scene": ("rtchannel.scene.spec", "Scene"),
    "Waveform": ("processing.radar.waveform", "Waveform"),
    "Isotropic": ("processing.radar.antenna", "Isotropic"),
    "GaussianBeam": ("processing.radar.antenna", "GaussianBeam"),
    "YagiBeam": ("processing.radar.antenna", "YagiBeam"),
    "ReceiverConfig": ("processing.radar.receiver", "ReceiverConfig"),
    "LeakageConfig": ("processing.radar.receiver", "LeakageConfig"),
    "RadarHardware": ("processing.radar.receiver", "RadarHardware"),
    "DSPConfig": ("processing.dsp.config", "DSPConfig"),
    # the chain: trace (the channel) -> synthesise (IQ, signatures); simulate = both
    "trace": ("rtchannel.pipeline", "trace"),
    "synthesise": ("rtchannel.pipeline", "synthesise"),
    "simulate": ("rtchannel.pipeline", "simulate"),
    "simulate_radars": ("rtchannel.pipeline", "simulate_radars"),
    "process": ("rtchannel.pipeline", "process"),
    "PathSets": ("rtchannel.results", "PathSets"),
    "PathSet": ("processing.pathset", "PathSet"),
    "SimulationResult": ("rtchannel.results", "SimulationResult"),
    "LinkResult": ("rtchannel.results", "LinkResult"),
    "Signature": ("processing.dsp.signatures", "Signature"),
    # figures: plot_* draw onto ax= and return the Figure; writing files is save_figure / save_figures
    "plot_pvt": ("processing.plots.signatures", "plot_pvt"),
    "plot_mean_velocity": ("processing.plots.signatures", "plot_mean_velocity"),
    "plot_range": ("processing.plots.signatures", "plot_range"),
    "plot_range_doppler": ("processing.plots.signatures", "plot_range_doppler"),
    "save_figure": ("processing.plots.signatures", "save_figure"),
    "save_figures": ("processing.plots.signatures", "save_figures"),
    # datasets and the classifier: what `rtchannel dataset / train / evaluate / crossval` run
    "build_dataset": ("rtchannel.dataset.build", "build_dataset"),
    "plan_dataset": ("rtchannel.dataset.build", "plan_dataset"),
    "load_dataset": ("processing.classifier.experiment", "load_dataset"),
    "train_classifier": ("processing.classifier.experiment", "train_classifier"),
    "evaluate_classifier": ("processing.classifier.experiment", "evaluate_classifier"),
    "crossvalidate": ("processing.classifier.experiment", "crossvalidate"),
    "read_crossval_plan": ("rtchannel.dataset.build", "read_crossval_plan"),
    # deprecated names, kept for one release (each warns when called)
    "load_signatures": ("rtchannel.results", "load_signatures"),  # -> SimulationResult.load(path)
    "plot_signatures": ("processing.plots.signatures", "plot_all"),  # -> save_figures(sigs, out_dir)
    "fetch": ("rtchannel.data_registry", "fetch"),  # third-party data (motion capture, real images) on demand
    "BACKENDS": ("rtchannel.backends", "BACKENDS"),
    "ACTIVITIES": ("processing.labels", "ACTIVITIES"),
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    if name not in _EXPORTS:
        raise AttributeError(f"module 'rtchannel' has no attribute {name!r}")
    import importlib

    module, attr = _EXPORTS[name]
    value = getattr(importlib.import_module(module), attr)
    globals()[name] = value
    return value


def __dir__():
    return sorted(list(globals()) + list(_EXPORTS))
