"""The point-set front end (paper Secs. 3, 4.1, 6): neighbourhoods, normals, DEM tangent
spaces, reconstruction weights, boundary loops, composed by :func:`build_frontend`."""

from .frontend import FrontEnd, build_frontend

__all__ = ["FrontEnd", "build_frontend"]
