"""The report of a run shaped like the quick suite stays within the issue's limits.

Issue 15: the quick suite's PDF at most 16 pages and its HTML at most 3 MB, one page per
surface. The run here has the quick suite's surfaces and method variants (read from
``parambench.bench.suites``, so the test follows the suite as methods are added) on small synthetic
meshes: most maps distinct (the worst case for panels), two pairs near-identical as in real
runs (fbcp-pc with the given boundary, libigl's SCP), and one failed cell.
"""

import json
import re
import subprocess
import zlib

import numpy as np
import pytest

from parambench.bench.suites import SUITES, expand_cells
from parambench.bench.schema import dataset_key
from parambench.reports.build import build_report

pytestmark = pytest.mark.slow  # one report with WeasyPrint, about half a minute

MAX_PAGES = 16
MAX_HTML_BYTES = 3_000_000
GRID = 16  # 256 points per surface: small, so the test is quick


def quick_shape():
    """(datasets, variants): the quick suite's surfaces and its (method, params) pairs."""
    cells = expand_cells(SUITES["quick"])
    datasets = list(dict.fromkeys(c.dataset for c in cells))
    variants = list(dict.fromkeys((c.method, tuple(c.params)) for c in cells))
    return datasets, variants


def distinct_uv(points, index):
    """A different affine-plus-bend map per variant, so no two are near-identical."""
    xy = points[:, :2]
    shear = np.array([[1.0, 0.04 * index], [0.0, 1.0 + 0.03 * index]])
    return xy @ shear.T + 0.05 * index * np.column_stack([xy[:, 1] ** 2, np.zeros(len(xy))])


def write_quick_shaped_run(root, tools):
    datasets, variants = quick_shape()
    cells_dir, datasets_dir = root / "cells", root / "datasets"
    cells_dir.mkdir(parents=True)
    datasets_dir.mkdir()
    labels = [m + json.dumps(dict(p), sort_keys=True) for m, p in variants]
    twin = {}  # variant index -> the variant whose map (similar) it repeats
    for a, b in ((("fbcp-pc", ()), ("fbcp-pc", (("boundary", "given"),))), (("scp", ()), ("scp-igl", ()))):
        if a in variants and b in variants:
            twin[variants.index(b)] = variants.index(a)
    rows = []
    for d, dataset in enumerate(datasets):
        name = dataset.replace("/", "-")
        points, faces, loop = tools["grid_mesh"](GRID, "bump" if d % 2 else "saddle")
        rng = np.random.default_rng(d)
        mask = np.zeros(len(points), dtype=bool)
        mask[loop] = True
        np.savez_compressed(datasets_dir / f"{dataset_key(name, GRID * GRID, 'poisson', 0.0, 0)}.npz",
                            w_tan_interior=rng.normal(0.17, 0.05, 500), w_tan_boundary=rng.normal(0.25, 0.2, 100),
                            points=points.astype(np.float32), det_boundary_mask=mask,
                            **tools["loops_arrays"]("gt", [loop]), **tools["loops_arrays"]("det", [loop]))
        for v, (method, params) in enumerate(variants):
            cell_id = f"{name}-s0-{method}-{zlib.crc32(labels[v].encode()):010d}"
            row = {"cell_id": cell_id, "dataset": name, "size": GRID * GRID, "sampling": "poisson", "noise": 0.0,
                   "seed": 0, "method": method, "params": json.dumps(dict(params)), "n_points": len(points),
                   "n_faces": len(faces), "artifact": "", "k_opt": None, "peak_memory_mb": 10.0,
                   "turning_numbers": "[]", "timings": "{}", "diagnostics": "{}", "eval_mesh": ""}
            if method == "bff-mouette" and d == 0:
                row.update(status="failed", error_type="NotADiskError", error="not a disk; use scp-igl.")
            else:
                uv = distinct_uv(points, v)
                if v in twin:  # rotated and scaled copy of its twin's map: the same picture
                    angle = 0.4
                    rot = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
                    uv = 2.0 * distinct_uv(points, twin[v]) @ rot.T
                qc = tools["per_face_qc"](points, faces, uv)
                flipped = tools["flipped_mask"](faces, uv)
                row.update(status="ok", error_type="", error="", qc_mean=float(qc.mean()),
                           qc_p95=float(np.quantile(qc, 0.95)), qc_max=float(qc.max()),
                           foldovers=int(flipped.sum()), foldover_fraction=float(flipped.mean()), collapsed=False,
                           area_distortion=0.1, exact_error=None, n_eval_faces=len(faces),
                           eval_mesh="ground-truth", time_total=0.1 + 0.01 * v,
                           artifact=f"cells/{cell_id}.npz")
                arrays = {"points": points.astype(np.float32), "faces": faces.astype(np.int32), "uv": uv, "qc": qc,
                          "flipped": flipped, **tools["loops_arrays"]("gt", [loop])}
                if method == "ocp":
                    row["k_opt"] = 3.0
                    k, energy, t = tools["landscape"](3.0)
                    arrays.update(landscape_k=k, landscape_E=energy, landscape_t=t)
                np.savez_compressed(cells_dir / f"{cell_id}.npz", **arrays)
            (cells_dir / f"{cell_id}.json").write_text(json.dumps(row))
            rows.append(row)
    (root / "run.json").write_text(json.dumps({"suite": "quick", "command": "parambench run", "seeds": [0]}))
    return datasets, variants, twin


@pytest.fixture(scope="module")
def quick_report(tmp_path_factory, mesh_tools):
    root = tmp_path_factory.mktemp("quick-shape") / "results"
    datasets, variants, twin = write_quick_shaped_run(root, mesh_tools)
    return {"paths": build_report(root), "datasets": datasets, "variants": variants, "twin": twin}


def pdf_pages(require_tool, path) -> list[str]:
    text = subprocess.run([require_tool("pdftotext"), "-layout", str(path), "-"], check=True, capture_output=True,
                          text=True).stdout
    info = subprocess.run([require_tool("pdfinfo"), str(path)], check=True, capture_output=True, text=True).stdout
    n_pages = int(re.search(r"^Pages:\s+(\d+)", info, flags=re.M).group(1))
    return text.split("\f")[:n_pages]


def test_the_run_has_the_quick_suites_shape(quick_report):
    datasets, variants = quick_report["datasets"], quick_report["variants"]
    assert len(datasets) == 7 and len(variants) >= 19  # as of issue 13 (real/spot-top); grows with the registry
    assert len(quick_report["twin"]) == 2


def test_pdf_and_html_within_the_issue_limits(quick_report, require_tool):
    pages = pdf_pages(require_tool, quick_report["paths"]["pdf"])
    assert len(pages) <= MAX_PAGES
    assert quick_report["paths"]["html"].stat().st_size <= MAX_HTML_BYTES


def test_each_surface_fits_one_page(quick_report, require_tool):
    pages = pdf_pages(require_tool, quick_report["paths"]["pdf"])
    surface_pages = [i for i, page in enumerate(pages) if re.search(r"^\s*Surface: ", page, flags=re.M)]
    assert len(surface_pages) == len(quick_report["datasets"])
    for i in surface_pages:
        # The row of small figures (its heading names the boundary panel) closes the surface.
        assert "Boundary detection" in pages[i], f"page {i + 1}: the surface spills onto the next page"
    # Nothing of a surface on the page after it: the next page is another surface or the end matter.
    for i in surface_pages:
        if i + 1 < len(pages) and i + 1 not in surface_pages:
            assert "Boundary detection" not in pages[i + 1] and "Checkerboard texture" not in pages[i + 1]


def test_near_identical_maps_share_a_panel_and_the_detail_view(quick_report):
    html = quick_report["paths"]["html"].read_text()
    variants = quick_report["variants"]
    figures = re.findall(r'<img id="[^"]+" src="data:[^"]+" alt="uv layouts[^"]*"[^>]* data-panels="([^"]+)"', html)
    assert len(figures) == len(quick_report["datasets"])
    panels = json.loads(figures[1].replace("&quot;", '"'))  # a surface where no cell failed
    assert panels["scp"] == panels["scp-igl"]
    assert panels["fbcp-pc"] == panels["fbcp-pc [boundary=given]"]
    # Every other variant keeps a box of its own.
    distinct = {tuple(box) for box in panels.values()}
    assert len(panels) == len(variants) and len(distinct) == len(variants) - len(quick_report["twin"])
    assert "Drawn once, near-identical maps" in html and "scp = scp-igl" in html


def test_per_cell_tables_are_in_the_html_only(quick_report, require_tool):
    html = quick_report["paths"]["html"].read_text()
    assert html.count('<table class="summary"') == len(quick_report["datasets"])
    text = "".join(pdf_pages(require_tool, quick_report["paths"]["pdf"]))
    assert "Seeds ok" not in text  # the per-cell tables' column
    assert "Median QC mean per method" in text and "per-cell summary tables" in text
