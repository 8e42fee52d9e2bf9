"""Motion: the pose sequence (`pose`: rig, `Motion`, forward kinematics), the procedural generators and the
motion-capture importers that build on it, retargeting onto the avatar rig, and motion-layer augmentation.

`Motion.procedural` and `Motion.from_file` are registered here: `pose` is the leaf every other module of
the package imports, so it cannot import the generators and importers itself.
"""
from rtchannel.motion import pose as _pose


def _procedural(activity: str, **params):
    import numpy as np

    from rtchannel.motion.procedural import ProceduralParams, generate

    if activity == "walk" and "start" not in params:  # centred on the origin along its heading
        p = ProceduralParams(**params)
        d = p.distance if p.distance is not None else (4.0 if p.duration is None else p.speed * p.duration)
        h = np.deg2rad(p.heading_deg)
        params = {**params, "start": (-d / 2 * np.cos(h), -d / 2 * np.sin(h))}
    return generate(activity, **params)


def _from_file(path, **options):
    from rtchannel.motion.load import load_motion

    return load_motion(path, **options)


_pose.FACTORIES.update(procedural=_procedural, file=_from_file)
