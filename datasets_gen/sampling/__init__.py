"""Samplings of a parameter domain: lattices, area-uniform random points, Poisson-disk sets, boundaries."""

#: The sampling names ``make_surface`` accepts.
SAMPLINGS = ("grid", "jittered", "random", "blue-noise")

__all__ = ["SAMPLINGS"]
