"""Radar DSP: range FFT, slow-time clutter removal (MTI), p(v,t), mean radial velocity, range distribution."""
