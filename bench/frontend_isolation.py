"""Which piece of ``ocp``'s point-set pipeline makes a map fold: ground truth substituted piece by piece.

A diagnostic, not a method: it needs a surface with its mesh (faces, true boundary
loops). :func:`isolate` runs ``ocp``'s pipeline (front end, Laplacian of the ``energy``
option, SCP with the k line search, output scaled as the plugin does) with any of three
pieces replaced by ground truth:

* ``true_normals``: per-vertex normals of the mesh (area-weighted face normals, unit)
  given to the front end; ``smooth=False`` also skips the front end's neighbourhood
  smoothing of them (which averages across a gap); ``normals_truth="surface"`` takes the
  surface's own normals instead (a generated surface's exact normals: under normal noise
  the noisy mesh's vertex normals carry the noise);
* ``true_loops``: the mesh's boundary loops (oriented by the faces) instead of the
  detected ones for the Laplacian's boundary term and the solve;
* ``mesh_neighbours``: the kNN graph replaced by the K nearest points within ``rings``
  mesh rings, so normals, DEM balls, weights and the boundary cannot bridge a gap
  (the noise refits of the normals still search Euclidean neighbourhoods).

:func:`truth_cut_knn` is the Euclidean kNN graph with the edges across a gap removed by the
ground truth (a ``graph`` to pass), and :func:`closer_elsewhere` counts the points of a noisy
sampling that lie nearer another part of the clean surface than their own: no method that
sees positions only can keep those on their side of a gap.

Each run reports QC mean and foldovers on the true mesh and where the flipped faces lie:
within 2 / 5 mesh rings of a *bridge* (an Euclidean kNN edge spanning more than
``bridge_rings`` mesh rings), within 2 rings of the true boundary, or elsewhere.
Found with it on ``real/camelhead`` (the lips) and ``fold`` under noise: see
``bench/MEASUREMENTS.md``. Run ``python -m parambench.bench.frontend_isolation real/camelhead`` for the
standard cases, ``python -m parambench.bench.frontend_isolation fold 2000 jittered 0 0.5``
for a generated surface (size, sampling, seed, noise in spacings).
"""

from __future__ import annotations

import contextlib
from dataclasses import replace

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import dijkstra

from parambench.bench.metrics import evaluate
from parambench.methods.pointset import frontend as _frontend
from parambench.methods.pointset.neighbourhoods import KnnGraph, knn_graph
from parambench.methods.pointset.params import FrontEndParams
from parambench.methods.pointset.plugin_support import scale_to_spacing
from parambench.methods.pointset.reorder import spatial_order
from parambench.methods.hints import method_hints
from parambench.methods.plugins.ocp import Ocp, conformal_problem, ocp_laplacian

__all__ = ["mesh_adjacency", "vertex_normals", "ring_distance", "mesh_ring_knn", "truth_cut_knn", "bridges",
           "closer_elsewhere", "oriented_loops", "flipped_faces", "isolate", "pruned_with_true_normals",
           "STANDARD_CASES", "main"]


def mesh_adjacency(n: int, faces: np.ndarray) -> sp.csr_matrix:
    """Vertex adjacency (0/1, symmetric, no diagonal) of a triangle mesh."""
    e = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    a = sp.csr_matrix((np.ones(len(e) * 2), (np.r_[e[:, 0], e[:, 1]], np.r_[e[:, 1], e[:, 0]])), shape=(n, n))
    a.data[:] = 1.0
    return a


def vertex_normals(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unit area-weighted vertex normals of a consistently oriented mesh."""
    fn = np.cross(points[faces[:, 1]] - points[faces[:, 0]], points[faces[:, 2]] - points[faces[:, 0]])
    out = np.zeros_like(points)
    for c in range(3):
        np.add.at(out, faces[:, c], fn)
    return out / np.maximum(np.linalg.norm(out, axis=1, keepdims=True), 1e-300)


def _reach(adjacency: sp.csr_matrix, rings: int) -> sp.csr_matrix:
    step = (adjacency + sp.identity(adjacency.shape[0], format="csr")).astype(bool)
    reach = sp.identity(adjacency.shape[0], format="csr", dtype=bool)
    for _ in range(rings):
        reach = (reach @ step).astype(bool)
    return reach.tocsr()


def ring_distance(adjacency: sp.csr_matrix, rows: np.ndarray, cols: np.ndarray, max_rings: int) -> np.ndarray:
    """Mesh-ring (hop) distance of vertex pairs, ``max_rings + 1`` where farther.

    Parameters
    ----------
    adjacency : (N, N) scipy.sparse.csr_matrix
        From :func:`mesh_adjacency`.
    rows, cols : (M,) numpy.ndarray of int
    max_rings : int

    Returns
    -------
    (M,) numpy.ndarray of int64
    """
    step = (adjacency + sp.identity(adjacency.shape[0], format="csr")).astype(bool)
    reach = sp.identity(adjacency.shape[0], format="csr", dtype=bool)
    out = np.full(len(rows), max_rings + 1, dtype=np.int64)
    for r in range(max_rings + 1):
        if r:
            reach = (reach @ step).astype(bool).tocsr()
        hit = np.asarray(reach[rows, cols]).ravel()
        out[(out > max_rings) & hit] = r
    return out


def mesh_ring_knn(points: np.ndarray, adjacency: sp.csr_matrix, k: int, rings: int = 3) -> KnnGraph:
    """The K Euclidean-nearest points within ``rings`` mesh rings of each vertex.

    Raises
    ------
    ValueError
        A vertex has fewer than K others within ``rings`` rings.
    """
    reach = _reach(adjacency, rings).tocoo()
    keep = reach.row != reach.col
    r, c = reach.row[keep], reach.col[keep]
    d = np.linalg.norm(points[c] - points[r], axis=1)
    order = np.lexsort((d, r))
    r, c, d = r[order], c[order], d[order]
    start = np.searchsorted(r, np.arange(points.shape[0]))
    count = np.diff(np.r_[start, len(r)])
    if count.min() < k:
        raise ValueError(f"a vertex has only {count.min()} others within {rings} rings; k={k}.")
    pick = start[:, None] + np.arange(k)[None, :]
    return KnnGraph(indices=c[pick].astype(np.int64), distances=d[pick], mean_spacing=float(d[pick].mean()))


def truth_cut_knn(points: np.ndarray, adjacency: sp.csr_matrix, k: int, rings: int = 6,
                  pool: int = 4) -> KnnGraph:
    """The Euclidean K nearest without the edges that span more than ``rings`` mesh rings.

    What a perfect gap test would leave of the Euclidean graph: each point keeps its K
    nearest among its ``pool * K`` nearest that lie within ``rings`` rings of it on the
    mesh (unlike :func:`mesh_ring_knn`, edges of up to ``rings`` rings, e.g. round a
    tight bend, stay). A row with fewer such candidates is filled with its nearest cut ones.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
    adjacency : (N, N) scipy.sparse.csr_matrix
        From :func:`mesh_adjacency`.
    k : int
    rings : int
        Ring span above which an edge counts as crossing a gap.
    pool : int
        Candidates per point, in units of K.

    Returns
    -------
    KnnGraph
        Rows nearest first, self excluded.
    """
    cand = knn_graph(points, min(points.shape[0] - 1, pool * k))
    m = cand.indices.shape[1]
    rows = np.repeat(np.arange(points.shape[0]), m)
    cut = (ring_distance(adjacency, rows, cand.indices.ravel(), rings) > rings).reshape(-1, m)
    pick = np.argsort(cut, axis=1, kind="stable")[:, :k]
    dist = np.take_along_axis(cand.distances, pick, axis=1)
    resort = np.argsort(dist, axis=1, kind="stable")
    idx = np.take_along_axis(np.take_along_axis(cand.indices, pick, axis=1), resort, axis=1)
    dist = np.take_along_axis(dist, resort, axis=1)
    return KnnGraph(indices=np.ascontiguousarray(idx), distances=np.ascontiguousarray(dist),
                    mean_spacing=float(dist.mean()))


def closer_elsewhere(points: np.ndarray, clean_points: np.ndarray, faces: np.ndarray, rings: int = 6,
                     subdivisions: int = 8) -> np.ndarray:
    """Points nearer to another part of the clean surface than to their own place on it.

    Each point of a noisy sampling is compared with the clean mesh (the same sampling
    without noise: ``make_surface(..., noise=0)`` with the same seed gives it): the
    nearest point of the clean mesh (among ``subdivisions``-times subdivided samples of
    every face, the face's nearest-corner vertex standing for it) more than ``rings``
    mesh rings from the point's own vertex means the noise carried the point past the
    middle of a gap. Positions alone cannot tell such a point's side: any neighbourhood
    built from them puts it on the other sheet.

    Parameters
    ----------
    points : (N, 3) numpy.ndarray of float64
        The noisy sampling.
    clean_points : (N, 3) numpy.ndarray of float64
        The same vertices without noise.
    faces : (F, 3) numpy.ndarray of int64
        The mesh of both.
    rings : int
    subdivisions : int
        Barycentric steps per face edge of the dense clean samples.

    Returns
    -------
    (M,) numpy.ndarray of int64
        The points, ascending.
    """
    from scipy.spatial import cKDTree

    t = np.linspace(0.0, 1.0, int(subdivisions) + 1)
    a, b = np.meshgrid(t, t)
    inside = a + b <= 1.0 + 1e-12
    bary = np.stack([1.0 - a[inside] - b[inside], a[inside], b[inside]], axis=1)  # (S, 3)
    samples = np.einsum("sk,fki->fsi", bary, clean_points[faces]).reshape(-1, 3)
    corner = faces[:, np.argmax(bary, axis=1)].reshape(-1)  # the sample's nearest corner
    _, near = cKDTree(samples).query(points)
    n = points.shape[0]
    far = ring_distance(mesh_adjacency(n, faces), np.arange(n), corner[near], rings) > rings
    return np.flatnonzero(far)


def bridges(points: np.ndarray, adjacency: sp.csr_matrix, k: int = 8, bridge_rings: int = 10) -> np.ndarray:
    """Vertices at an end of a Euclidean kNN edge spanning more than ``bridge_rings`` rings."""
    g = knn_graph(points, k)
    rows = np.repeat(np.arange(points.shape[0]), k)
    cols = g.indices.ravel()
    far = ring_distance(adjacency, rows, cols, bridge_rings) > bridge_rings
    return np.unique(np.concatenate([rows[far], cols[far]]))


def oriented_loops(faces: np.ndarray, loops) -> list[np.ndarray]:
    """Boundary loops ordered along their faces' edges (counter-clockwise seen from the normals)."""
    edges = {(int(a), int(b)) for a, b in np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])}
    out = []
    for loop in loops:
        loop = np.asarray(loop, dtype=np.int64)
        out.append(loop if (int(loop[0]), int(loop[1])) in edges else loop[::-1].copy())
    return out


def flipped_faces(uv: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Indices of the faces whose uv orientation is against the majority (or degenerate)."""
    e1 = uv[faces[:, 1]] - uv[faces[:, 0]]
    e2 = uv[faces[:, 2]] - uv[faces[:, 0]]
    area = e1[:, 0] * e2[:, 1] - e1[:, 1] * e2[:, 0]
    sign = 1.0 if (area > 0).sum() >= (area < 0).sum() else -1.0
    return np.flatnonzero(area * sign <= 0)


@contextlib.contextmanager
def _front_end_patched(points: np.ndarray, graph: KnnGraph | None, skip_normal_check: bool):
    """Swap the front end's kNN graph (mapped to its kd-tree order) and/or its user-normals check."""
    saved = _frontend.knn_graph, _frontend.check_user_normals
    if graph is not None:
        order = spatial_order(points)  # the order knn_stage uses
        inv = np.empty_like(order)
        inv[order] = np.arange(order.size)

        def ring_graph(_sorted_points, _k):
            return KnnGraph(indices=inv[graph.indices[order]], distances=graph.distances[order],
                            mean_spacing=graph.mean_spacing)

        _frontend.knn_graph = ring_graph
    if skip_normal_check:  # mesh normals are consistent by construction
        _frontend.check_user_normals = lambda *args, **kwargs: None
    try:
        yield
    finally:
        _frontend.knn_graph, _frontend.check_user_normals = saved


def isolate(surface, *, true_normals: bool = False, smooth: bool = True, true_loops: bool = False,
            mesh_neighbours: bool = False, rings: int = 3, graph: KnnGraph | None = None, energy: str = "neumann",
            params: FrontEndParams | None = None, bridge_rings: int = 10, context: dict | None = None,
            normals_truth: str = "mesh") -> dict:
    """Run ``ocp``'s pipeline on ``surface.points`` with ground-truth pieces substituted.

    Parameters
    ----------
    surface : parambench.datasets_gen.surface.Surface
        With ``faces`` and ``boundary_loops`` (the ground truth).
    true_normals : bool
        Give the mesh's vertex normals to the front end.
    smooth : bool
        The front end's normal smoothing (``FrontEndParams.smooth_normals``).
    true_loops : bool
        Solve with the mesh's boundary loops instead of the detected ones.
    mesh_neighbours : bool
        Replace the kNN graph by :func:`mesh_ring_knn` with ``rings``.
    rings : int
    graph : KnnGraph, optional
        Any neighbour graph (input order) to use instead of the kNN graph, e.g.
        :func:`pruned_with_true_normals`; overrides ``mesh_neighbours``.
    energy : str
        ``ocp``'s ``energy`` option.
    params : FrontEndParams, optional
        Front-end options (defaults when omitted); ``smooth`` overrides ``smooth_normals``.
    bridge_rings : int
        Ring span above which a kNN edge counts as a bridge (fold location).
    context : dict, optional
        Reused between calls on the same surface (adjacency, normals, bridges, distances).
    normals_truth : {"mesh", "surface"}
        The true normals (given with ``true_normals`` and the reference of
        ``normal_error_deg``): the mesh's vertex normals, or ``surface.normals`` (a
        generated surface's exact normals, which a noisy sampling's mesh does not have).

    Returns
    -------
    dict
        ``qc_mean``, ``foldovers``, ``k_opt``, ``n_loops`` and ``recall`` (of the true
        outer loop by the detected loops), ``normal_error_deg`` (median angle of the front
        end's oriented normals to the mesh's, at all points and at bridge ends),
        ``normal_sign_flips``, and ``folds_near`` {``bridge2``, ``bridge5``,
        ``boundary2``, ``elsewhere``} (flipped faces by nearest vertex ring distance).
    """
    pts, faces = surface.points, surface.faces
    n = pts.shape[0]
    ctx = context if context is not None else {}
    if "adjacency" not in ctx:
        adj = mesh_adjacency(n, faces)
        ctx["adjacency"] = adj
        ctx["normals"] = vertex_normals(pts, faces)
        ctx["bridges"] = bridges(pts, adj, FrontEndParams().k_nn, bridge_rings)
        loops_all = np.concatenate([np.asarray(lp) for lp in surface.boundary_loops])
        ctx["d_bridge"] = (dijkstra(adj, indices=ctx["bridges"], unweighted=True, min_only=True)
                           if len(ctx["bridges"]) else np.full(n, np.inf))
        ctx["d_boundary"] = dijkstra(adj, indices=loops_all, unweighted=True, min_only=True)
    if normals_truth == "mesh":
        truth = ctx["normals"]
    elif normals_truth == "surface" and surface.normals is not None:
        truth = surface.normals / np.linalg.norm(surface.normals, axis=1, keepdims=True)
    else:
        raise ValueError(f"normals_truth must be 'mesh' or 'surface' (with surface.normals), got {normals_truth!r}.")
    opts = replace(params or FrontEndParams(), smooth_normals=bool(smooth))
    if graph is None and mesh_neighbours:
        graph = mesh_ring_knn(pts, ctx["adjacency"], int(opts.k_nn), rings)
    if graph is not None:  # the substitute replaces the Euclidean kNN search (the patched knn_graph)
        opts = replace(opts, neighbours="euclidean")
    with _front_end_patched(pts, graph, skip_normal_check=true_normals):
        front = _frontend.build_frontend(pts, truth if true_normals else None, opts)
    detected = front.boundary_loops
    if true_loops:
        loops = oriented_loops(faces, surface.boundary_loops)
        mask = np.zeros(n, dtype=bool)
        mask[np.concatenate(loops)] = True
        front = replace(front, boundary_loops=loops, boundary_mask=mask)
    lap = ocp_laplacian(front, energy)
    # Outside Method.__call__: fit error hints to ocp's parameters here (issue 11, item 7).
    with method_hints(Ocp.defaults, {**Ocp.defaults, "energy": energy}):
        sol = conformal_problem(front, lap).solve("scp", "line")
    uv = scale_to_spacing(sol.uv, front)
    m = evaluate(pts, faces, uv)
    cos = np.einsum("ij,ij->i", front.normals, truth)
    ang = np.degrees(np.arccos(np.clip(np.abs(cos), 0.0, 1.0)))
    flip = flipped_faces(uv, faces)
    near_b = ctx["d_bridge"][faces[flip]].min(axis=1) if flip.size else np.zeros(0)
    near_l = ctx["d_boundary"][faces[flip]].min(axis=1) if flip.size else np.zeros(0)
    outer = np.asarray(surface.boundary_loops[0])
    return {
        "qc_mean": float(m["qc_mean"]), "foldovers": int(m["foldovers"]), "k_opt": float(sol.k),
        "n_loops": len(detected), "recall": float(np.isin(outer, np.concatenate(detected)).mean()),
        "normal_error_deg": {"all": float(np.median(ang)),
                             "bridges": float(np.median(ang[ctx["bridges"]])) if len(ctx["bridges"]) else 0.0},
        "normal_sign_flips": int((cos < 0).sum()),
        "folds_near": {"bridge2": int((near_b <= 2).sum()), "bridge5": int((near_b <= 5).sum()),
                       "boundary2": int((near_l <= 2).sum()),
                       "elsewhere": int(((near_b > 5) & (near_l > 2)).sum())},
        "uv": uv,
    }


def pruned_with_true_normals(surface, k: int = 8) -> KnnGraph:
    """``neighbours="pruned"``'s graph with the mesh's normals in its plane tests and orientation.

    What the pruning would cut if its normal estimates (PCA on the nearest few, oriented
    along the pruned graph) were exact: separates a bad test from bad normals.
    """
    from parambench.methods.pointset import surface_neighbours as sn

    truth = vertex_normals(surface.points, surface.faces)
    saved = sn.pca_normals, sn.consistent_signs
    sn.pca_normals = lambda points, indices: truth
    sn.consistent_signs = lambda points, normals, indices: np.where(
        np.einsum("ij,ij->i", normals, truth) < 0, -1.0, 1.0)
    try:
        return sn.pruned_knn_graph(surface.points, k)[0]
    finally:
        sn.pca_normals, sn.consistent_signs = saved


#: The substitutions of :func:`main`: label -> keyword arguments of :func:`isolate`.
STANDARD_CASES = {
    "estimated (ocp as is)": {},
    "true normals": {"true_normals": True},
    "true normals, unsmoothed": {"true_normals": True, "smooth": False},
    "true loops": {"true_loops": True},
    "mesh neighbours": {"mesh_neighbours": True},
    "mesh neighbours + true normals": {"mesh_neighbours": True, "true_normals": True},
    "mesh neighbours + true normals + true loops": {"mesh_neighbours": True, "true_normals": True, "true_loops": True},
    "neighbours=pruned": {"params": FrontEndParams(neighbours="pruned")},
    "neighbours=pruned + true normals": {"params": FrontEndParams(neighbours="pruned"), "true_normals": True},
}


def main(argv=None) -> int:
    """Print one JSON line per case of :data:`STANDARD_CASES` for a dataset (default ``real/camelhead``).

    Arguments: ``NAME [N SAMPLING SEED NOISE]``; with ``N`` a generated surface of that
    size, sampling (default jittered), seed (0) and normal noise in spacings (0). Under
    noise the true normals are the surface's exact ones (``normals_truth="surface"``)
    and the last line also counts :func:`closer_elsewhere`. Cases that raise print the
    error.
    """
    import json
    import sys

    from parambench.datasets_gen.errors import ParambenchError
    from parambench.datasets_gen.registry import make_surface

    args = sys.argv[1:] if argv is None else list(argv)
    name = args[0] if args else "real/camelhead"
    if len(args) > 1:
        size, sampling = int(args[1]), args[2] if len(args) > 2 else "jittered"
        seed, noise = (int(args[3]) if len(args) > 3 else 0), (float(args[4]) if len(args) > 4 else 0.0)
        surface = make_surface(name, size, sampling=sampling, seed=seed, noise=noise)
    else:
        noise = 0.0
        surface = make_surface(name)
    truth = "surface" if noise > 0 and surface.normals is not None else "mesh"
    ctx: dict = {}
    cases = dict(STANDARD_CASES)
    pruned_true = pruned_with_true_normals(surface)
    cases["pruned graph cut with true normals"] = {"graph": pruned_true}
    cases["pruned graph cut with true normals + true normals"] = {"graph": pruned_true, "true_normals": True}
    cut = truth_cut_knn(surface.points, mesh_adjacency(surface.n_points, surface.faces), FrontEndParams().k_nn)
    cases["Euclidean graph cut by the truth"] = {"graph": cut}
    cases["Euclidean graph cut by the truth + true normals"] = {"graph": cut, "true_normals": True}
    for label, kwargs in cases.items():
        try:
            out = isolate(surface, context=ctx, normals_truth=truth, **kwargs)
        except (ParambenchError, ValueError) as exc:  # a refusal is a finding here
            print(json.dumps({"case": label, "error": f"{type(exc).__name__}: {exc}"}), flush=True)
            continue
        out.pop("uv")
        print(json.dumps({"case": label, **out}), flush=True)
    summary = {"bridge_ends": int(len(ctx["bridges"])), "normals_truth": truth}
    if noise > 0:  # the same sampling without noise: the noise has a random stream of its own
        clean = make_surface(name, size, sampling=sampling, seed=seed, noise=0.0)
        summary["closer_elsewhere"] = int(closer_elsewhere(surface.points, clean.points, surface.faces).size)
    print(json.dumps(summary))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
