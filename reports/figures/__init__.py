"""One module per kind of picture; each returns a :class:`Picture` (a PNG data URI)."""

from ._common import MAX_FACES_PER_PANEL, Picture
from .benchmark import benchmark_figure
from .boundary import BoundaryPanel, boundary_figure, boundary_scores
from .checkerboard import checkerboard_figure
from .landscape import LandscapeCurve, landscape_figure
from .scaling import fit_power_law, scaling_figure, scaling_fits
from .sdp_curve import sdp_curve_figure
from .uv_layout import LayoutPanel, uv_layout_figure
from .weights import negative_fractions, weights_figure

__all__ = [
    "MAX_FACES_PER_PANEL",
    "Picture",
    "benchmark_figure",
    "BoundaryPanel",
    "boundary_figure",
    "boundary_scores",
    "checkerboard_figure",
    "LandscapeCurve",
    "landscape_figure",
    "fit_power_law",
    "scaling_figure",
    "scaling_fits",
    "sdp_curve_figure",
    "LayoutPanel",
    "uv_layout_figure",
    "negative_fractions",
    "weights_figure",
]
