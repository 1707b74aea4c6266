"""The fragment content of each generation written by fragment_writer.py (deterministic)."""
import numpy as np


def generation_points(generation):
    """Points of one generation: their count and values both depend on it."""
    rng = np.random.default_rng(generation)
    return rng.uniform(-10.0, 10.0, size=(20000 + 3000 * (generation % 7), 3))
