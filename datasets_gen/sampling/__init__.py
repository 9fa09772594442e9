"""Samplings of a parameter domain: lattices, area-uniform random points, Poisson-disk sets (uniform or
graded by a sizing field), boundaries."""

#: The sampling names ``make_surface`` accepts.
SAMPLINGS = ("grid", "jittered", "random", "blue-noise", "graded")

__all__ = ["SAMPLINGS"]
