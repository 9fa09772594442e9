"""Built-in method plugins; importing this package registers them."""

from . import lscm_igl, scp_igl  # noqa: F401
