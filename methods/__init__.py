"""Parameterization methods: shared numerics plus one small plugin module per method."""

from .base import Method, MethodOutput, Parameterization, StageTimer
from .registry import get_method, method_names, register

__all__ = ["Method", "MethodOutput", "Parameterization", "StageTimer", "get_method", "method_names", "register"]
