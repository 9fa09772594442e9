"""Shared numerics on triangle meshes: topology checks, Laplacian weights, conformal energy."""
