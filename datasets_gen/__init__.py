"""Surfaces for the suite: procedural generators, real meshes and user files."""

from .errors import ParambenchError
from .surface import Surface

__all__ = ["ParambenchError", "Surface"]
