"""Real meshes and point sets.

- ``real/camelhead``, ``real/lilium``, ``real/bump-domain``: disk-topology meshes from the
  libigl tutorial data; ``real/meg-helmet``: a MEG helmet surface, an example mesh of the
  bfieldtools package (BSD-3-Clause); ``real/spot-top``: Keenan Crane's Spot (public domain)
  cut open by a plane; ``real/cortex-lh``: pycortex's demo cortex (BSD-2-Clause) cut to its
  flat map and decimated; ``real/lidar-ground``: the ground returns of an airborne LiDAR
  tile from laspy's test data (BSD-2-Clause), bare points with a hole where no return came
  back, given a reference triangulation in the xy plane
  (:func:`parambench.datasets_gen.height_field.height_field_surface`). All are shipped as
  package data in ``datasets_gen/data/real/`` (sources, licences and the cut in
  ``SOURCES.md`` there), so a clone anywhere and an installed wheel
  both find them; the environment variable ``PARAMBENCH_REAL_DATA`` points the loader at
  another folder.
- ``real/bunny10k``, ``real/chameleon``: files shipped in the pymeshlab wheel
  (``tests/sample_meshes/``), found from ``pymeshlab.__file__``.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import igl
import numpy as np

from .errors import InputFileError
from .io import load_surface
from .surface import Surface

__all__ = ["REAL_DATASETS", "RealDataset", "PACKAGE_DATA_DIR", "real_data_dir", "pymeshlab_samples_dir",
           "pymeshlab_terrain", "load_real"]

ENV_VAR = "PARAMBENCH_REAL_DATA"


#: The meshes shipped inside the package, beside this module (a source tree and an
#: unpacked wheel lay them out alike, so no project-relative path is involved).
PACKAGE_DATA_DIR = Path(__file__).resolve().parent / "data" / "real"


def real_data_dir() -> Path:
    """Folder of the shipped real meshes.

    Returns
    -------
    pathlib.Path
        ``$PARAMBENCH_REAL_DATA`` when that environment variable is set and not empty,
        otherwise :data:`PACKAGE_DATA_DIR` (``datasets_gen/data/real`` of this package).
        The folder is not checked here: :func:`load_real` says which file is missing.
    """
    override = os.environ.get(ENV_VAR)
    if override:
        return Path(override)
    return PACKAGE_DATA_DIR


def pymeshlab_samples_dir() -> Path:
    """The sample meshes folder inside the installed pymeshlab package."""
    import pymeshlab

    return Path(pymeshlab.__file__).resolve().parent / "tests" / "sample_meshes"


def pymeshlab_terrain(steps: int = 7, height: float = 0.3, seed: int = 1) -> Surface:
    """pymeshlab's ridged fractal terrain (``create_fractal_terrain``) as a Surface.

    A height field made by another tool: a ``2**steps + 1`` square grid of points, one rim;
    its mesh and rim are the ground truth. From height 0.3 (at 7 steps) knife-edge ridges
    fall under the sampling scale.

    Parameters
    ----------
    steps : int
        Grid refinement steps (7: 129 x 129 = 16,641 points).
    height : float
        ``maxheight``, in [0, 1].
    seed : int
        pymeshlab's seed: the same terrain for the same seed.

    Returns
    -------
    Surface
        Named ``pymeshlab/terrain-h{height}-s{seed}``, with faces and boundary loops.
    """
    import pymeshlab

    from .mesh_loops import mesh_boundary

    ms = pymeshlab.MeshSet()
    ms.create_fractal_terrain(steps=int(steps), maxheight=float(height), seed=float(seed))
    points = np.asarray(ms.current_mesh().vertex_matrix(), dtype=np.float64)
    faces = np.asarray(ms.current_mesh().face_matrix(), dtype=np.int64)
    loops, mask = mesh_boundary(faces, len(points))
    return Surface(points=points, faces=faces, name=f"pymeshlab/terrain-h{height:g}-s{seed}",
                   params={"steps": int(steps), "height": float(height), "seed": int(seed)},
                   boundary_loops=loops, boundary_mask=mask)


@dataclass(frozen=True)
class RealDataset:
    """A real file: where it lives and what it is."""

    name: str
    filename: str
    location: str  # "package" (shipped with parambench, see real_data_dir) or "pymeshlab"
    description: str
    points_only: bool = False
    #: "height-field": a point file given the reference triangulation of
    #: :func:`~parambench.datasets_gen.height_field.height_field_surface`.
    reference: str | None = None

    def path(self) -> Path:
        folder = real_data_dir() if self.location == "package" else pymeshlab_samples_dir()
        return folder / self.filename


REAL_DATASETS = {d.name: d for d in (
    RealDataset("real/camelhead", "camelhead.off", "package",
                "camel head scan, disk mesh, 11381 vertices (libigl tutorial data)"),
    RealDataset("real/lilium", "lilium.obj", "package", "lilium petal, disk mesh, 3389 vertices (libigl tutorial data)"),
    RealDataset("real/bump-domain", "bump-domain.obj", "package",
                "bumpy domain, disk mesh, 4172 vertices (libigl tutorial data)"),
    RealDataset("real/meg-helmet", "meg-helmet.obj", "package",
                "MEG helmet surface, deep dome, disk mesh, 2044 vertices (bfieldtools example mesh)"),
    RealDataset("real/spot-top", "spot-top.obj", "package",
                "Spot the cow cut by a plane below the back, head and ears kept, disk mesh, 2089 vertices"),
    RealDataset("real/cortex-lh", "cortex-lh.obj", "package",
                "folded cortex (white matter, left hemisphere) cut to its flat map, disk mesh, 12226 vertices "
                "(pycortex demo subject S1)"),
    RealDataset("real/bunny10k", "bunny10k_textured.obj", "pymeshlab",
                "Stanford bunny, 5051 vertices, open with 5 holes (pymeshlab sample)"),
    RealDataset("real/chameleon", "chameleon.pts", "pymeshlab",
                "chameleon point set with normals, 4594 points, no faces (pymeshlab sample)", points_only=True),
    RealDataset("real/lidar-ground", "lidar-ground.xyz", "package",
                "airborne LiDAR ground returns (LAS class 2), 9808 points, a hole where no return came back; "
                "reference mesh: xy Delaunay less voids and rim slivers (laspy test data)",
                points_only=True, reference="height-field"),
)}


def load_real(name: str, *, seed: int | None = 0, noise: float = 0.0, requested: dict | None = None) -> Surface:
    """Load a real dataset; mesh datasets get area-weighted vertex normals from their faces.

    Parameters
    ----------
    name : str
        A key of :data:`REAL_DATASETS`.
    seed : int or None
        Seeds the noise.
    noise : float
        Gaussian displacement along the normals, as a fraction of the mean edge length
        (meshes) or of the mean nearest-neighbour distance (point sets).
    requested : dict, optional
        The caller's ``n_points`` and ``sampling``, recorded as ignored.

    Returns
    -------
    Surface
        ``params``: ``n_points`` (the actual count), ``sampling`` None, ``noise``, ``file``,
        ``ignored`` (the requested size and sampling, which do not apply).

    Raises
    ------
    InputFileError
        The file is not where it should be (the message says where it looked).
    """
    from .build import add_normal_noise, mean_edge_length

    spec = REAL_DATASETS[name]
    path = spec.path()
    if not path.is_file():
        if spec.location != "package":
            where = f"the pymeshlab package's sample folder {path.parent} (reinstall pymeshlab)"
        elif os.environ.get(ENV_VAR):
            where = f"{path.parent}, the folder {ENV_VAR} names (unset it to use the meshes shipped with parambench)"
        else:
            where = (f"the package data folder {path.parent} (reinstall parambench, "
                     f"or set {ENV_VAR} to a folder holding {spec.filename})")
        raise InputFileError(f"{name}: {spec.filename} not found in {where}.")
    surface = load_surface(path, name=name, points_only=spec.points_only)
    if spec.reference == "height-field":
        from .height_field import height_field_surface

        surface = height_field_surface(surface.points, name)
    normals = surface.normals
    if normals is None and surface.faces is not None:
        normals = np.asarray(igl.per_vertex_normals(surface.points, surface.faces,
                                                    igl.PER_VERTEX_NORMALS_WEIGHTING_TYPE_AREA), dtype=np.float64)
    points = surface.points
    if noise > 0:
        if normals is None:
            raise InputFileError(f"{name}: no normals to add noise along.")
        spacing = (mean_edge_length(points, surface.faces) if surface.faces is not None
                   else _mean_neighbour_distance(points))
        points = add_normal_noise(points, normals, noise * spacing, np.random.default_rng(seed))
    normals_from = "file" if surface.normals is not None else ("mesh, area-weighted" if normals is not None else None)
    params = {"n_points": surface.n_points, "sampling": None, "noise": float(noise), "file": spec.filename,
              "normals": normals_from, "ignored": dict(requested or {}),
              **({"reference": spec.reference, **surface.params} if spec.reference else {})}
    return Surface(points=points, faces=surface.faces, normals=normals, name=name, params=params, seed=seed,
                   boundary_mask=surface.boundary_mask, boundary_loops=surface.boundary_loops)


def _mean_neighbour_distance(points: np.ndarray) -> float:
    from scipy.spatial import cKDTree

    dist, _ = cKDTree(points).query(points, k=2)
    return float(dist[:, 1].mean())
