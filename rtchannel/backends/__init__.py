"""Scattering backends: each turns a pose sequence into a PathSet per radar link."""
