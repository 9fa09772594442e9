"""Which methods' maps of one surface are the same picture.

Several methods minimise nearly the same energy (cotangent SCP, libigl's SCP, DNCP with
two pins, free-boundary point-cloud LSCM on the mesh's own points) and return maps that
differ by less than a pixel once rotated and scaled onto a panel. Drawing each one again
made the surface pages spill onto a second page and doubled the report's image bytes
without showing the reader anything new, so such maps share one panel that names them all.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["MapGroup", "similarity_distance", "group_maps", "SAME_MAP_TOLERANCE"]

#: Largest :func:`similarity_distance` at which two maps share a panel: 0.2 % of the map's
#: RMS radius, a fraction of a pixel on a panel of a few hundred pixels.
SAME_MAP_TOLERANCE = 2e-3


@dataclass
class MapGroup:
    """Variants drawn by one panel; the first is the one drawn.

    Attributes
    ----------
    members : list of str
        Variant labels, in the order given to :func:`group_maps`.
    indices : list of int
        Their positions in that input.
    """

    members: list = field(default_factory=list)
    indices: list = field(default_factory=list)

    def label(self, max_chars: int = 48) -> str:
        """The panel title: the names joined by " = ", cut to "(+N more)" past ``max_chars``."""
        shown = [self.members[0]]
        for name in self.members[1:]:
            if len(" = ".join(shown + [name])) > max_chars:
                break
            shown.append(name)
        rest = len(self.members) - len(shown)
        return " = ".join(shown) + (f" (+{rest} more)" if rest else "")


def similarity_distance(uv_a: np.ndarray, uv_b: np.ndarray) -> float:
    """How far two maps of the same points are from being similar (rotation, reflection, scale, shift).

    The residual of the best similarity taking one centred map onto the other, relative to
    its size: ``sqrt(1 - (sum sigma)^2 / (|A|^2 |B|^2))`` with sigma the singular values of
    ``A^T B`` (orthogonal Procrustes). 0 for similar maps, 1 at most. Symmetric in a and b.

    Parameters
    ----------
    uv_a, uv_b : (N, 2) numpy.ndarray of float64
        Row i of both is the image of the same point.

    Returns
    -------
    float
        ``inf`` when the shapes differ, a map is not finite, or a map collapses to a point.
    """
    if uv_a.shape != uv_b.shape or not (np.isfinite(uv_a).all() and np.isfinite(uv_b).all()):
        return float("inf")
    a = uv_a - uv_a.mean(axis=0)
    b = uv_b - uv_b.mean(axis=0)
    norm = float((a * a).sum() * (b * b).sum())
    if norm <= 0.0:
        return float("inf")
    sigma = np.linalg.svd(a.T @ b, compute_uv=False).sum()
    return float(np.sqrt(max(0.0, 1.0 - sigma * sigma / norm)))


def group_maps(labels, points, uvs, keys=None, tolerance: float = SAME_MAP_TOLERANCE) -> list[MapGroup]:
    """Group maps of one surface that would draw the same panel.

    A map joins the first group whose drawn map is on the same points, has the same ``key``
    and lies within ``tolerance`` (:func:`similarity_distance`); otherwise it starts a group.
    Comparing with the drawn map only (not any member) keeps every member within the
    tolerance of the picture, so groups never chain.

    Parameters
    ----------
    labels : sequence of str
    points : sequence of (N_i, 3) numpy.ndarray of float64
        Each map's surface points (maps on different points are never grouped).
    uvs : sequence of (N_i, 2) numpy.ndarray of float64
    keys : sequence of hashable, optional
        What must also be equal (e.g. foldover count and status), so a panel's title holds for
        every member.
    tolerance : float

    Returns
    -------
    list of MapGroup
        In the order of each group's first member; every index appears once.

    Raises
    ------
    ValueError
        The sequences differ in length.
    """
    labels, points, uvs = list(labels), list(points), list(uvs)
    keys = list(keys) if keys is not None else [None] * len(labels)
    if not len(labels) == len(points) == len(uvs) == len(keys):
        raise ValueError(f"group_maps: {len(labels)} labels, {len(points)} point sets, {len(uvs)} maps and "
                         f"{len(keys)} keys; pass one of each per map.")
    groups: list[MapGroup] = []
    for i, label in enumerate(labels):
        for group in groups:
            j = group.indices[0]
            if (keys[j] == keys[i] and points[j].shape == points[i].shape and np.allclose(points[j], points[i])
                    and similarity_distance(uvs[j], uvs[i]) <= tolerance):
                group.members.append(label)
                group.indices.append(i)
                break
        else:
            groups.append(MapGroup([label], [i]))
    return groups
