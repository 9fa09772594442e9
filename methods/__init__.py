"""Parameterization methods: shared numerics plus one small plugin module per method."""

from .numba_threading import prefer_openmp

prefer_openmp()  # before any kernel module is imported; see numba_threading

from .base import Method, MethodOutput, Parameterization, StageTimer  # noqa: E402
from .registry import get_method, method_names, register  # noqa: E402

__all__ = ["Method", "MethodOutput", "Parameterization", "StageTimer", "get_method", "method_names", "register"]
