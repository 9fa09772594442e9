"""``ocp`` on points scattered at random over a real mesh: a ragged boundary, no point on it.

The generated surfaces place points along their boundary curves; scans do not. On
``real/lilium`` the default Neumann energy's map crossed its own boundary (2k points) or
its k search found no regular map (5k, 20k); the paper's energy maps 2k and 5k, at QC
1.28x / 1.10x the true mesh's map, and nothing maps 20k. Refined by cotangent SCP on
their own uv mesh (20k: an sdp map's), all three come within 3 %.
"""

from __future__ import annotations

import numpy as np
import pytest

from parambench.bench.metrics import evaluate, flipped_mask, triangle_signed_areas
from parambench.datasets_gen.registry import make_surface
from parambench.methods.pointset.frontend import build_frontend
from parambench.methods.pointset.loop_untangle import local_crossings
from parambench.methods.registry import get_method
from parambench.methods.spectral.turning import loop_turning_numbers


def _scattered(name: str, n: int, seed: int = 0):
    """Points scattered over a real mesh, the scp-igl map of their reference triangulation and its QC.

    The yardstick of issue #11: libigl's conformal map of the reference triangulation
    (:func:`parambench.datasets_gen.scattered.scatter_on_mesh`), the mesh of these points.
    """
    surface = make_surface(name, n, sampling="scattered", seed=seed)
    reference = get_method("scp-igl")(surface).uv
    return surface, evaluate(surface.points, surface.faces, reference)["qc_mean"], reference


def _folds_off_rim_slivers(surface, uv) -> int:
    """Flipped reference triangles, less slivers with every corner on the reference's rim."""
    faces = surface.faces
    flipped = flipped_mask(triangle_signed_areas(uv, faces))
    p = surface.points[faces]
    longest = np.linalg.norm(p - p[:, [1, 2, 0]], axis=2).max(axis=1)
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    rim_sliver = surface.boundary_mask[faces].all(axis=1) & (area < 0.05 * longest**2)
    return int(np.count_nonzero(flipped & ~rim_sliver))


@pytest.mark.parametrize("n, how", [(2000, "retry"), (5000, "fallback"), (20000, "mesh")])
def test_scattered_points_on_a_real_mesh_get_a_conformal_map(n, how):
    surface, reference_qc, _ = _scattered("real/lilium", n)
    result = get_method("ocp")(surface.method_input(False))
    check, diag = result.diagnostics["selfcheck"], result.diagnostics
    assert check["passed"], check["reason"]
    # Facing the normals, as the loops are oriented: an sdp pair has no handedness of its own.
    assert check["mirrored"] is False and check["turning_numbers"] == [1.0]
    if how == "retry":  # the Neumann map crossed its boundary: the self-check's second retry
        assert check["retry"]["params"] == {"energy": "paper", "refine": "mesh"}
        assert check["retry"]["earlier"][0]["params"] == {"k_nn": 12}
    else:  # the Neumann k search failed: the solve's own fallback, its error kept
        assert diag["energy_error"].startswith("ConvergenceError")
        # ... at once: the exact searches on the dense boundary reduction (6-50 s on these
        # data, a map found once in 8 runs) are left to the paper energy's fallback.
        assert "the exact searches were left for the caller's fallback" in diag["energy_error"]
    if how == "mesh":  # the paper energy's search failed too: the mesh of the unrolled boundary's map
        assert diag["energy_used"] == "mesh" and diag["refined"]["first_map"] == "unrolled boundary"
    else:  # the paper energy's map, refined on its own uv mesh
        assert diag["energy_used"] == "paper" and diag["refined"]["first_map"] == "ocp (paper energy)"
    quality = evaluate(surface.points, surface.faces, result.uv)
    # A fold only in the reference's rim slivers (three outermost points nearly in line,
    # whose order across the chord no map fixes) is the reference's ambiguity: measured 1 at 20k.
    assert _folds_off_rim_slivers(surface, result.uv) == 0 and quality["foldovers"] <= 2
    # Issue #11's target: within 3 % of scp-igl on the points' own mesh. Measured 1.0028x /
    # 1.0012x / 1.0014x; unrefined, the paper energy's maps were 1.28x / 1.10x (2k / 5k).
    assert quality["qc_mean"] < 1.03 * reference_qc


def test_without_refinement_lilium_20k_has_no_map():
    from parambench.datasets_gen.errors import ConvergenceError

    surface = make_surface("real/lilium", 20000, sampling="scattered", seed=0)
    with pytest.raises(ConvergenceError, match=r"use refine='auto'") as err:  # the remedy comes first
        get_method("ocp")(surface.method_input(False), refine="none")
    # The search the first attempt ran without its exact fallbacks ran again last with them
    # (here over 500 boundary points: not affordable, and the message says how to ask for it).
    message = str(err.value)
    assert "the line search failed" in message and "left for the caller" not in message
    assert "k_search='direct' was not tried on" in message


def test_scattered_boundary_loop_turns_once_in_the_true_map():
    # At 20k points the walk and the points put back into it visited three points within
    # 0.4 spacings of each other in the wrong order: a curl that turned the loop twice in
    # the reference map itself, so no k could give a regular map. The loop is untangled.
    surface, _, ref_uv = _scattered("real/lilium", 20000)
    front = build_frontend(surface.points)
    assert len(front.boundary_loops) == 1 and front.diagnostics["boundary"]["n_untangled"] >= 1
    assert np.abs(loop_turning_numbers(ref_uv, front.boundary_loops)).tolist() == [1]
    assert local_crossings(front.points, front.normals, front.boundary_loops[0]).size == 0


@pytest.mark.parametrize("n,aspect,seed,refined", [(3000, 1.0, 8, True), (4000, 4.0, 3, False), (3000, 1.0, 1, True)])
def test_a_stretched_map_of_a_developable_tile_is_caught_and_refined(n, aspect, seed, refined):
    """Uniform random points on z = 0.06 sin(x) over [-a, a] x [-1, 1], as a LiDAR tile
    comes (no point on the rim). The surface is developable: (arc length along x, y) is
    its exact conformal map. These two seeds' first maps pass every other check but are
    stretched (13.5 % and 3.4 % of the diameter off the development, coherent Beltrami
    coefficient 0.40 / 0.27); the check fails them as "distorted" and the retries
    (``refine=mesh``, then ``k_nn=12``) give the development to 2.5e-5 / 1.0e-5. The third
    seed's first map, once its rim was complete (the front end wraps the points a loop left
    outside), is a Neumann-energy map 5.6 % of the diameter off with a coherent coefficient
    of only 0.097, under the old limit of 0.15; clean inputs are now held to 0.06. The
    second seed's first map, stretched with a point outside its loop before the wrap took
    corner points in too (fortieth session), then failed on its loop crossing itself in uv
    (turning +2: the paper energy's map unrefined, its uv mesh having a vertex with two
    fans); since the mesh keeps the larger fan (forty-fourth session) the first run gives
    the development (9.3e-8 of the diameter off; the retry gave 8.8e-8).

    The stretched Neumann maps of the first and third seeds have k_opt 1.86 and 1.53, far
    from the 1 at which its area and Dirichlet terms agree: since the forty-seventh
    session ``refine="auto"`` refines them on their uv mesh at once, where before the
    check failed them as stretched and the retries refined them."""
    from scipy.integrate import cumulative_trapezoid

    from parambench.bench.metrics import similarity_align
    from parambench.datasets_gen.surface import MethodInput

    rng = np.random.default_rng(seed)
    xy = rng.uniform(-1, 1, (n, 2)) * [aspect, 1.0]
    points = np.c_[xy, 0.06 * np.sin(xy[:, 0])]
    x = np.linspace(-aspect, aspect, 20001)
    arc = cumulative_trapezoid(np.sqrt(1.0 + (0.06 * np.cos(x)) ** 2), x, initial=0.0)
    exact = np.c_[np.interp(xy[:, 0], x, arc), xy[:, 1]]
    ocp = get_method("ocp")
    result = ocp(MethodInput(points))
    check = result.diagnostics["selfcheck"]
    assert check["passed"], check["reason"]
    assert not check.get("retry")
    if refined:
        from parambench.methods.plugins.ocp import NEUMANN_K_TOLERANCE

        unrefined = ocp.run(MethodInput(points), **{**ocp.defaults, "refine": "none"})
        assert abs(unrefined.diagnostics["k_opt"] - 1.0) > NEUMANN_K_TOLERANCE
        assert result.diagnostics["refined"] is not None
    assert check["coherent_beltrami"] < 0.01
    aligned = similarity_align(result.uv, exact)
    rms = np.sqrt(np.mean(np.sum((aligned - exact) ** 2, axis=1)))
    assert rms < 1e-3 * np.linalg.norm(np.ptp(exact, axis=0))


@pytest.mark.parametrize("hole, first_map", [(False, "unrolled boundary"), (True, "plane projection")])
def test_an_elongated_random_tile_maps_through_a_first_map_without_k(hole, first_map):
    """8000 uniform random points on a flat 10 x 1 rectangle (a corridor scan, no point on
    the rim). Both energies' k searches find no regular map and SDP's pair runs twice
    along the length (its second eigenvector is the first one's overtone): ConvergenceError
    before the projection and the unrolled boundary, at 20k points on 4:1 to 100:1 strips
    too. With one loop the unrolled boundary's map gives the mesh; with a hole (two loops,
    which it does not unroll) the projection on the plane across the mean normal does
    (the surface is a height field over it). Cotangent SCP on either mesh is the plane's
    own map (measured 1.6e-11 / 5.8e-11 of the diagonal)."""
    from parambench.bench.metrics import similarity_align
    from parambench.datasets_gen.surface import MethodInput

    rng = np.random.default_rng(3)
    xy = rng.uniform(0.0, 1.0, (8000, 2)) * [10.0, 1.0]
    if hole:
        xy = xy[np.hypot(xy[:, 0] - 5.0, xy[:, 1] - 0.5) > 0.25]
    result = get_method("ocp")(MethodInput(np.c_[xy, np.zeros(len(xy))]))
    check = result.diagnostics["selfcheck"]
    assert check["passed"], check["reason"]
    assert len(check["turning_numbers"]) == 1 + hole
    assert result.diagnostics["refined"]["first_map"] == first_map
    aligned = similarity_align(result.uv, xy)
    assert np.sqrt(np.mean(np.sum((aligned - xy) ** 2, axis=1))) < 1e-8 * np.hypot(10.0, 1.0)


def test_height_field_projection_only_where_no_normal_turns_past_the_limit():
    from parambench.methods.plugins.ocp import height_field_projection

    rng = np.random.default_rng(0)
    xy = rng.uniform(-1.0, 1.0, (500, 2))
    turn = np.linalg.qr(rng.standard_normal((3, 3)))[0]
    tilted = np.c_[xy, np.zeros(len(xy))] @ turn.T + [3.0, -2.0, 7.0]
    flat = height_field_projection(tilted, np.tile(turn[:, 2], (len(xy), 1)))
    assert flat is not None
    # The projection is the plane's own coordinates, up to a rigid motion.
    np.testing.assert_allclose(np.linalg.norm(flat[1:] - flat[0], axis=1),
                               np.linalg.norm(xy[1:] - xy[0], axis=1), atol=1e-9)
    theta = rng.uniform(0.0, 0.49 * np.pi, 500)  # a hemisphere: normals up to 88 degrees off
    phi = rng.uniform(0.0, 2.0 * np.pi, 500)
    normals = np.c_[np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)]
    assert height_field_projection(normals, normals) is None
