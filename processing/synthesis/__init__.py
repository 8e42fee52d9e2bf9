"""The shared FMCW beat-signal synthesiser: raw IQ from path sets (exact and gridded), only what the DSP
consumes (projection), and signal-layer augmentation."""
