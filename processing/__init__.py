"""processing: the path-set contract, FMCW synthesis, radar DSP and metrics (lower layer).

This package knows nothing of meshes, motion or Mitsuba and never imports `rtchannel`.
"""
