"""Shared plumbing of the report's pictures: PNG data URIs, face subsampling, a 3D view.

Figures are built with :class:`matplotlib.figure.Figure` directly (no pyplot), which
renders with the Agg canvas and touches no global state, so building a report does not
change the caller's matplotlib backend and is safe in worker threads.
"""

from __future__ import annotations

import base64
import io
import textwrap
from dataclasses import dataclass, field

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.text import Text
from PIL import Image

__all__ = [
    "Picture",
    "MAX_FACES_PER_PANEL",
    "DPI",
    "new_figure",
    "figure_to_picture",
    "subsample_faces",
    "splat",
    "view_projection",
    "face_normals",
    "overlapping_texts",
    "wrap_label",
]

#: Triangles drawn per panel at most; more are subsampled (foldovers always kept).
MAX_FACES_PER_PANEL = 50_000
#: Resolution of every PNG.
DPI = 110
#: JPEG quality of shaded pictures (checkerboards): artefacts stay below what print and a
#: screen at 100 % show, at about two thirds of the bytes of quality 82.
JPEG_QUALITY = 72


@dataclass
class Picture:
    """One rendered figure.

    Attributes
    ----------
    title : str
    caption : str
        What the picture shows and how to read it.
    data_uri : str
        ``data:image/png;base64,...``.
    width_px, height_px : int
        Pixel size of the PNG.
    rows : int
        Rows of panels (the print layout gives each row about a third of a page).
    panels : dict of str to (4,) tuple of float
        Where each labelled panel (with its title) lies in the image, as fractions of its
        width and height from the top left: ``(left, top, right, bottom)``. The HTML detail
        view crops these.
    text_overlaps : list of (str, str)
        Pairs of texts whose bounding boxes intersect in the rendered image (should be empty).
    config : str
        The surface configuration the panels belong to ("" when not per surface).
    print_row_px : int or None
        Printed height per row of panels in CSS px (None: the page default).
    """

    title: str
    caption: str
    data_uri: str
    width_px: int
    height_px: int
    rows: int = 1
    panels: dict = field(default_factory=dict)
    text_overlaps: list = field(default_factory=list)
    config: str = ""
    print_row_px: int | None = None


def new_figure(width_in: float, height_in: float, layout: str | None = "constrained") -> Figure:
    """A white figure of the given size in inches (constrained layout unless ``layout=None``).

    It is attached to an Agg canvas, so text extents can be measured after drawing.
    """
    fig = Figure(figsize=(width_in, height_in), facecolor="white", layout=layout)
    FigureCanvasAgg(fig)
    return fig


def overlapping_texts(fig: Figure) -> list[tuple[str, str]]:
    """Pairs of visible, non-empty texts of a drawn figure whose bounding boxes intersect.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
        Already drawn (after ``savefig`` or ``canvas.draw``), so positions are final.

    Returns
    -------
    list of (str, str)
    """
    renderer = _renderer(fig)
    tick_labels, drawn_ticks = set(), []
    for ax in fig.axes:
        for axis in (ax.xaxis, ax.yaxis):
            # Only the ticks the axis draws (inside its view interval), not the spare ones; asked
            # first, because asking may create tick objects.
            drawn = axis._update_ticks() if ax.axison and axis.get_visible() else []
            for tick in axis.majorTicks + axis.minorTicks:
                tick_labels.update((id(tick.label1), id(tick.label2)))
            for tick in drawn:
                drawn_ticks += [t for t in (tick.label1, tick.label2) if t.get_visible()]
    texts = [t for t in fig.findobj(Text) if id(t) not in tick_labels] + drawn_ticks
    boxes = []
    for text in texts:
        if not text.get_visible() or not text.get_text().strip() or text.figure is None:
            continue
        if text.axes is not None and not text.axes.get_visible():
            continue
        box = text.get_window_extent(renderer)
        if box.width > 0 and box.height > 0:
            boxes.append((text.get_text(), box))
    out = []
    for i, (a, box_a) in enumerate(boxes):
        for b, box_b in boxes[i + 1:]:
            # Strict overlap: boxes that only touch (stacked tick labels) do not count.
            if (min(box_a.x1, box_b.x1) - max(box_a.x0, box_b.x0) > 0.5
                    and min(box_a.y1, box_b.y1) - max(box_a.y0, box_b.y0) > 0.5):
                out.append((a, b))
    return out


def _renderer(fig: Figure):
    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    return canvas.get_renderer()


def wrap_label(text: str, width_in: float, fontsize: float, max_lines: int = 3) -> str:
    """Wrap a panel title to the panel's width (about 0.6 em per character).

    Parameters
    ----------
    text : str
    width_in : float
        Panel width in inches.
    fontsize : float
        In points.
    max_lines : int
        Longer text is cut with an ellipsis.
    """
    chars = max(8, int(width_in * 72 / (0.62 * fontsize)))
    lines = []
    for part in text.split("\n"):
        lines += textwrap.wrap(part, chars, break_long_words=True, break_on_hyphens=False) or [""]
    if len(lines) > max_lines:
        lines = lines[:max_lines]
        lines[-1] = lines[-1][: chars - 1] + "…"
    return "\n".join(lines)


def _draw_pixels(fig: Figure, dpi: int) -> Image.Image:
    """Lay out and draw the figure once at ``dpi`` on its Agg canvas; its pixels on white.

    One draw serves the PNG, the JPEG and the panel positions: each ``savefig`` would run
    the constrained layout and draw every artist again (three draws per figure cost about
    two thirds of a report's build time).
    """
    fig.set_dpi(dpi)
    fig.patch.set_facecolor("white")
    canvas = fig.canvas if isinstance(fig.canvas, FigureCanvasAgg) else FigureCanvasAgg(fig)
    canvas.draw()
    rgba = Image.fromarray(np.asarray(canvas.buffer_rgba()).copy(), mode="RGBA")
    # As matplotlib's own JPEG writer does: composite on the (white) face colour.
    rgb = Image.new("RGB", rgba.size, "white")
    rgb.paste(rgba, mask=rgba.getchannel("A"))
    return rgb


def _png(image: Image.Image) -> bytes:
    buffer = io.BytesIO()
    image.save(buffer, format="png")
    return buffer.getvalue()


def _jpeg(image: Image.Image) -> bytes:
    buffer = io.BytesIO()
    image.save(buffer, format="jpeg", quality=JPEG_QUALITY, optimize=True)
    return buffer.getvalue()


def _palette_png(image: Image.Image) -> bytes:
    """The PNG with at most 256 colours (no dithering), which is what a plot of lines and flat fills uses.

    Line plots, histograms and viridis-shaded layouts hold a few hundred distinct colours
    (mostly antialiasing); one byte per pixel instead of three makes them 2 to 4 times smaller
    with no visible change at print size.
    """
    quantized = image.quantize(colors=256, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    buffer = io.BytesIO()
    quantized.save(buffer, format="png", optimize=True)
    return buffer.getvalue()


def figure_to_picture(fig: Figure, title: str, caption: str = "", dpi: int = DPI, rows: int = 1,
                      panel_axes: dict | None = None, fmt: str = "auto") -> Picture:
    """Render a figure to a data URI (PNG, or JPEG where that is smaller).

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    title, caption : str
    dpi : int
    rows : int
        Rows of panels in the figure.
    panel_axes : dict of str to matplotlib Axes, optional
        Panels to locate in the image (:attr:`Picture.panels`).
    fmt : {"auto", "png", "jpeg"}
        "auto" keeps the smaller of PNG and JPEG: line plots stay PNG, shaded surfaces
        become JPEG (often four times smaller, the difference invisible at print size).
        A PNG is stored with a 256-colour palette when that is smaller.

    Returns
    -------
    Picture
    """
    image = _draw_pixels(fig, dpi)
    if fmt == "jpeg":
        data, kind = _jpeg(image), "jpeg"
    else:
        data, kind = min(_png(image), _palette_png(image), key=len), "png"
    if fmt == "auto":
        jpeg = _jpeg(image)
        if len(jpeg) < 0.85 * len(data):  # JPEG only when clearly smaller: it blurs thin lines
            data, kind = jpeg, "jpeg"
    width, height = image.size
    uri = f"data:image/{kind};base64," + base64.b64encode(data).decode("ascii")
    panels = {}
    if panel_axes:
        renderer = _renderer(fig)
        fw, fh = fig.bbox.width, fig.bbox.height
        for label, ax in panel_axes.items():
            box = ax.get_tightbbox(renderer)
            panels[label] = (max(0.0, box.x0 / fw), max(0.0, 1 - box.y1 / fh), min(1.0, box.x1 / fw),
                             min(1.0, 1 - box.y0 / fh))
    return Picture(title, caption, uri, width, height, rows, panels, overlapping_texts(fig))


def subsample_faces(n_faces: int, limit: int = MAX_FACES_PER_PANEL, keep: np.ndarray | None = None,
                    seed: int = 0) -> np.ndarray:
    """Indices of the faces to draw: all of them, or ``limit`` chosen at random.

    Parameters
    ----------
    n_faces : int
    limit : int
        Most faces to return.
    keep : (n_faces,) numpy.ndarray of bool, optional
        Faces that are always kept (foldovers), even past ``limit``.
    seed : int
        Seed of the random choice.

    Returns
    -------
    (K,) numpy.ndarray of int64
        Sorted indices; ``K = n_faces`` when ``n_faces <= limit``.
    """
    if n_faces <= limit:
        return np.arange(n_faces, dtype=np.int64)
    rng = np.random.default_rng(seed)
    chosen = np.zeros(n_faces, dtype=bool)
    chosen[rng.choice(n_faces, size=limit, replace=False)] = True
    if keep is not None:
        chosen |= np.asarray(keep, dtype=bool)
    return np.flatnonzero(chosen)


def splat(verts: np.ndarray, n_faces: int) -> np.ndarray:
    """Enlarge subsampled triangles about their centroids so that they cover the surface.

    Drawing a random fraction f of a mesh's triangles leaves gaps. Random pieces that just
    add up to the area still leave about e^-1 of it bare, so each drawn triangle is scaled
    by ``sqrt(8 / f)`` (capped at 5): eight-fold cover leaves about e^-8 bare. Panels hold a
    few hundred pixels and these meshes tens of thousands of triangles, so a triangle is
    about a pixel and the enlarged ones a few; QC and texture vary smoothly, so the
    overlaps do not show.

    Parameters
    ----------
    verts : (K, 3, 2) numpy.ndarray of float64
        Corners of the K drawn triangles.
    n_faces : int
        Faces of the whole mesh (K <= n_faces).

    Returns
    -------
    (K, 3, 2) numpy.ndarray of float64
        ``verts`` itself when nothing was left out.
    """
    if len(verts) >= n_faces or not len(verts):
        return verts
    scale = min(5.0, float(np.sqrt(8.0 * n_faces / len(verts))))
    centres = verts.mean(axis=1, keepdims=True)
    return centres + scale * (verts - centres)


def face_normals(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit face normals, (M, 3) float64 (zero for degenerate faces)."""
    p = points[faces]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, length, out=np.zeros_like(n), where=length > 0)


def view_projection(points: np.ndarray, faces: np.ndarray | None = None, tilt_deg: float = 35.0,
                    turn_deg: float = 25.0):
    """An orthographic camera that looks at a surface patch from slightly off its normal.

    The camera frame comes from the principal axes of the points: looking straight along
    the least-variance axis (the average normal of a disk-like patch) shows the outline,
    and tilting by ``tilt_deg`` about the main axis (after turning by ``turn_deg`` about
    the normal) shows the relief. With faces, the camera sits on the side their
    (area-weighted) normals point to, so a bump is seen as a bump and not as a dent.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    faces : (M, 3) integer numpy.ndarray, optional
    tilt_deg, turn_deg : float

    Returns
    -------
    xy : (N, 2) numpy.ndarray of float64
        Screen coordinates.
    depth : (N,) numpy.ndarray of float64
        Distance along the viewing direction (larger is nearer the camera).
    view : (3,) numpy.ndarray of float64
        Unit vector from the surface towards the camera.
    """
    points = np.asarray(points, dtype=np.float64)
    centred = points - points.mean(axis=0)
    # Rows of vt are the principal axes, by decreasing variance; a deterministic sign per axis.
    _, _, vt = np.linalg.svd(centred[:: max(1, len(points) // 20000)], full_matrices=False)
    signs = np.sign(vt[np.arange(3), np.argmax(np.abs(vt), axis=1)])
    axes = vt * np.where(signs == 0, 1.0, signs)[:, None]
    axes[2] = np.cross(axes[0], axes[1])  # right-handed, so the picture is never mirrored
    if faces is not None and len(faces):
        p = points[faces]
        mean_normal = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]).sum(axis=0)
        if mean_normal @ axes[2] < 0:
            axes[1:] *= -1.0  # a half-turn about the main axis: still right-handed
    a, b = np.radians(tilt_deg), np.radians(turn_deg)
    tilt = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    turn = np.array([[np.cos(b), -np.sin(b), 0], [np.sin(b), np.cos(b), 0], [0, 0, 1]])
    frame = tilt @ turn @ axes  # rows: screen x, screen y, towards the camera
    local = centred @ frame.T
    return local[:, :2], local[:, 2], frame[2]
