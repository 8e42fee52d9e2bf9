"""The ray-tracing scene: Mitsuba/Sionna RT scene with the deformable body, scene descriptions, LLVM
discovery for Dr.Jit, asset folders and the scene renderer.

Kept import-free so that `rtchannel.scene.llvm` can run before any dependency is installed (Makefile).
"""
