"""Surfaces for the suite: procedural generators, real meshes and user files."""

from .errors import ParambenchError
from .surface import MethodInput, Surface

__all__ = ["MethodInput", "ParambenchError", "Surface"]
