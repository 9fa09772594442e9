"""Built-in method plugins, one module per method named after it (``scp-tan`` in ``scp_tan.py``).

Importing this package imports every module here whose name does not start with an
underscore, which registers its plugin; modules starting with one (``_sklearn.py``)
hold what several plugins share and register nothing.
"""

from importlib import import_module
from pkgutil import iter_modules

# Sorted, so the import (and registration) order does not depend on the file system.
for _module in sorted(m.name for m in iter_modules(__path__)):
    if not _module.startswith("_"):
        import_module(f"{__name__}.{_module}")
del _module
