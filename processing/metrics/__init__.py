"""Validation metrics: normalised DTW (Table I), p(v,t) distances, simulated-against-real tables."""
