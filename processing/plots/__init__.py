"""Figures: signatures (spectrograms, mean velocity, range-time) and classifier plots."""
