"""The activity names, in a module without dependencies: the CLI's argument parser reads them before any
command runs, and importing `rtchannel.motion.procedural` for them would load scipy.interpolate."""

ACTIVITIES = ("fall", "walk", "stand", "sit", "pick")

__all__ = ["ACTIVITIES"]
