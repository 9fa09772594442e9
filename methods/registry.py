"""Registry of method plugins: the built-ins plus third-party ones from entry points.

Third-party packages register a plugin class under the entry-point group
``parambench.methods``::

    [project.entry-points."parambench.methods"]
    my-method = "my_package.module:MyMethod"
"""

from __future__ import annotations

from importlib import import_module
from importlib.metadata import entry_points

from parambench.datasets_gen.errors import UnknownNameError

from .base import Method

__all__ = ["register", "get_method", "method_names", "all_methods", "ENTRY_POINT_GROUP"]

ENTRY_POINT_GROUP = "parambench.methods"

_REGISTRY: dict[str, type[Method]] = {}
_LOADED = False


def register(cls: type[Method]) -> type[Method]:
    """Class decorator adding a plugin to the registry under ``cls.name``."""
    if not cls.name:
        raise ValueError(f"{cls.__qualname__} has no name")
    _REGISTRY[cls.name] = cls
    return cls


def _load() -> None:
    global _LOADED
    if _LOADED:
        return
    _LOADED = True
    import_module("parambench.methods.plugins")
    for ep in entry_points(group=ENTRY_POINT_GROUP):
        cls = ep.load()
        if not (isinstance(cls, type) and issubclass(cls, Method)):
            raise TypeError(f"entry point {ep.name!r} in {ENTRY_POINT_GROUP} is not a Method subclass")
        _REGISTRY.setdefault(cls.name, cls)


def get_method(name: str) -> Method:
    """An instance of the registered plugin ``name``.

    Raises
    ------
    UnknownNameError
        Unknown name; the message lists the registered ones.
    """
    _load()
    try:
        return _REGISTRY[name]()
    except (KeyError, TypeError):  # TypeError: an unhashable name, e.g. a list
        raise UnknownNameError(
            f"unknown method {name!r}; available: {', '.join(sorted(_REGISTRY))}. Run 'parambench list'."
        ) from None


def method_names() -> list[str]:
    """Sorted names of all registered methods."""
    _load()
    return sorted(_REGISTRY)


def all_methods() -> dict[str, type[Method]]:
    """Name to plugin class, sorted by name."""
    _load()
    return dict(sorted(_REGISTRY.items()))
