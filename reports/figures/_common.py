"""Shared plumbing of the report's pictures: PNG data URIs, face subsampling, a 3D view.

Figures are built with :class:`matplotlib.figure.Figure` directly (no pyplot), which
renders with the Agg canvas and touches no global state, so building a report does not
change the caller's matplotlib backend and is safe in worker threads.
"""

from __future__ import annotations

import base64
import io
from dataclasses import dataclass

import numpy as np
from matplotlib.figure import Figure

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
]

#: Triangles drawn per panel at most; more are subsampled (foldovers always kept).
MAX_FACES_PER_PANEL = 50_000
#: Resolution of every PNG.
DPI = 110


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
    """

    title: str
    caption: str
    data_uri: str
    width_px: int
    height_px: int
    rows: int = 1


def new_figure(width_in: float, height_in: float, layout: str | None = "constrained") -> Figure:
    """A white figure of the given size in inches (constrained layout unless ``layout=None``)."""
    return Figure(figsize=(width_in, height_in), facecolor="white", layout=layout)


def figure_to_picture(fig: Figure, title: str, caption: str = "", dpi: int = DPI, rows: int = 1) -> Picture:
    """Render a figure to a PNG data URI.

    Parameters
    ----------
    fig : matplotlib.figure.Figure
    title, caption : str
    dpi : int
    rows : int
        Rows of panels in the figure.

    Returns
    -------
    Picture
    """
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=dpi, facecolor="white")
    png = buffer.getvalue()
    # PNG header: 8-byte signature, then the IHDR chunk whose data starts with width, height.
    width = int.from_bytes(png[16:20], "big")
    height = int.from_bytes(png[20:24], "big")
    uri = "data:image/png;base64," + base64.b64encode(png).decode("ascii")
    return Picture(title, caption, uri, width, height, rows)


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
