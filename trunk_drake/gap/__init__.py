"""Sim-to-real gap diagnosis: where the model departs from data, which unmodelled effect explains it, how far the gap shrinks."""
