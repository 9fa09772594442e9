"""The point-set front end (paper Secs. 3, 4.1, 6): neighbourhoods, normals, DEM tangent
spaces, reconstruction weights, boundary loops, composed by :func:`build_frontend` with the
options of :class:`FrontEndParams`."""

from .frontend import FrontEnd, build_frontend
from .params import FrontEndParams

__all__ = ["FrontEnd", "FrontEndParams", "build_frontend"]
