"""Radar hardware: the FMCW waveform, antenna patterns, and the receiver (transmit power, thermal noise)."""
