"""Build the HTML and PDF report of a results directory.

The report only reads what the sweep stored (rows, npz arrays, run metadata, optional
pytest-benchmark files); it never runs a method. Missing pieces (no arrays for big cells,
no dataset diagnostics, no landscape, a single size) leave their picture out with a note,
and failed cells are reported, not dropped.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd

from datasets_gen.errors import InputFileError

from .benchmarks import load_benchmarks
from .errors import EmptyResultsError
from .figures import (BoundaryPanel, LandscapeCurve, LayoutPanel, benchmark_figure, boundary_figure,
                      checkerboard_figure, landscape_figure, scaling_figure, scaling_fits, uv_layout_figure,
                      weights_figure)
from .html import Note, Section, render_report
from .labels import add_labels
from .load import CellArrays, Results, load_cell_arrays, load_dataset_arrays, load_results
from .pdf import write_pdf
from .selection import PictureView, dataset_npz_candidates, picture_views
from .tables import (MEASURED_STATUSES, benchmark_table, exponent_table, failures_table, metadata_table,
                     overview_table, suspect_table,
                     stage_memory_table, summarise, summary_tables)

__all__ = ["build_report", "render_html", "EmptyResultsError", "FORMATS"]

FORMATS = ("html", "pdf")
_SOURCE_PACKAGES = ("methods", "datasets_gen", "bench", "reports", "tests")
_MAX_BOUNDARY_PANELS = 6


def _check_out_dir(out_dir: Path) -> None:
    repo = Path(__file__).resolve().parent.parent
    target = out_dir.resolve()
    for name in _SOURCE_PACKAGES:
        package = repo / name
        if target == package or package in target.parents:
            raise InputFileError(
                f"Refusing to write the report into the source tree ({target}); pass an output folder "
                f"outside {package} (the default is RESULTS_DIR/report).")


def _load_arrays(results: Results, artifact: str, warnings: list[str]) -> CellArrays | None:
    try:
        arrays = load_cell_arrays(results.root, artifact)
    except InputFileError as exc:
        warnings.append(f"no picture from {artifact}: {exc}")
        return None
    if arrays is not None:
        warnings.extend(arrays.problems)
    return arrays


def _view_section(results: Results, view: PictureView, warnings: list[str]) -> Section:
    section = Section(f"Surface: {view.title}", new_page=True)
    panels: list[LayoutPanel] = []
    not_drawn: list[str] = []
    cell_arrays: dict[str, CellArrays] = {}
    for row in view.rows.itertuples():
        if row.status not in MEASURED_STATUSES:
            not_drawn.append(f"{row.variant} (failed: {row.error_type or 'error'})")
            continue
        arrays = _load_arrays(results, row.artifact, warnings)
        if arrays is None:
            not_drawn.append(f"{row.variant} (no stored arrays)")
            continue
        cell_arrays[row.variant] = arrays
        panels.append(LayoutPanel(row.variant, arrays, row.qc_mean, row.foldovers))

    try:
        surface = load_dataset_arrays(results.root, dataset_npz_candidates(view))
    except InputFileError as exc:
        warnings.append(str(exc))
        surface = None

    if panels:
        section.blocks.append(Section("uv layouts", [uv_layout_figure(panels, view.title)]))
        section.blocks.append(Section("Checkerboard texture",
                                      [checkerboard_figure([(p.label, p.arrays) for p in panels], view.title)]))
    else:
        section.blocks.append(Note("No method stored uv arrays for this surface, so there are no layout "
                                   "pictures (cells above the artifact size limit store none).", "muted"))
    if not_drawn:
        section.blocks.append(Note("Not drawn: " + "; ".join(not_drawn) + ".", "muted"))

    boundary = _boundary_panels(view, surface, cell_arrays)
    if boundary:
        section.blocks.append(Section("Boundary detection", [boundary_figure(boundary, view.title)]))

    curves = []
    for row in view.rows.itertuples():
        arrays = cell_arrays.get(row.variant)
        if arrays is not None and arrays.landscape is not None and len(arrays.landscape["k"]):
            land = arrays.landscape
            curves.append(LandscapeCurve(row.variant, land["k"], land["E"], land["t"], row.k_opt))
    if curves:
        section.blocks.append(Section("OCP landscape", [landscape_figure(curves, view.title)]))

    if surface is not None:
        picture = weights_figure(surface, view.title)
        if picture is not None:
            section.blocks.append(Section("Weight histograms", [picture]))
    return section


def _boundary_panels(view: PictureView, surface: dict | None, cell_arrays: dict) -> list[BoundaryPanel]:
    panels = []
    surface_gt = None
    if surface is not None and "points" in surface:
        points = np.asarray(surface["points"], dtype=np.float64)
        surface_gt = surface.get("gt_loops")
        mask = surface.get("det_boundary_mask")
        mask = np.asarray(mask, dtype=bool) if mask is not None and len(mask) == len(points) else None
        # Any method's evaluation mesh of the same points tells which side is the front.
        faces = next((a.faces for a in cell_arrays.values() if len(a.points) == len(points)), None)
        if mask is not None or surface.get("det_loops") is not None:
            panels.append(BoundaryPanel("point-set front end", points, surface_gt, mask, surface.get("det_loops"),
                                        faces))
    for variant, arrays in cell_arrays.items():
        if arrays.det_loops is None:
            continue
        gt = arrays.gt_loops
        if gt is None and surface is not None and len(surface.get("points", ())) == len(arrays.points):
            gt = surface_gt
        panels.append(BoundaryPanel(variant, arrays.points, gt, None, arrays.det_loops, arrays.faces))
    return panels[:_MAX_BOUNDARY_PANELS]


def _subtitle(run: dict, rows: pd.DataFrame) -> str:
    parts = []
    if run.get("suite"):
        parts.append(f"suite {run['suite']}")
    if run.get("date"):
        parts.append(str(run["date"]))
    version = run.get("package_version")
    commit = run.get("git_commit")
    if version or commit:
        parts.append(f"parambench {version or '?'}" + (f" @ {str(commit)[:10]}" if commit else ""))
    n_ok, n_suspect = int((rows["status"] == "ok").sum()), int((rows["status"] == "suspect").sum())
    parts.append(f"{len(rows)} cells, {n_ok} ok, " + (f"{n_suspect} suspect, " if n_suspect else "")
                 + f"{len(rows) - n_ok - n_suspect} failed")
    return " · ".join(parts)


def render_html(results: Results, benchmark_json=()) -> str:
    """The report page for loaded results.

    Parameters
    ----------
    results : Results
        From :func:`reports.load.load_results`.
    benchmark_json : iterable of path-like
        pytest-benchmark JSON files to include.

    Returns
    -------
    str
        A complete self-contained HTML document.

    Raises
    ------
    InputFileError
        A benchmark file is unreadable.
    """
    paths = [Path(p) for p in benchmark_json]
    stats = load_benchmarks(paths) if paths else None  # first: a bad file fails before the slow part
    warnings = list(results.warnings)
    rows = add_labels(results.rows)
    summary = summarise(rows)
    n_ok, n_suspect = int((rows["status"] == "ok").sum()), int((rows["status"] == "suspect").sum())
    sections: list[Section] = []

    overview = Section("Overview", intro=(
        f"{len(rows)} cells: {n_ok} ok, " + (f"{n_suspect} suspect (map failed its self-check), " if n_suspect else "")
        + f"{len(rows) - n_ok - n_suspect} failed; {rows['variant'].nunique()} method "
        f"variant(s) on {rows['config'].nunique()} surface configuration(s). Values are medians over seeds; "
        f"every metric is lower-is-better."))
    if n_ok + n_suspect == 0:
        overview.blocks.append(Note("Every cell failed: the tables below list the errors.", "warning"))
    overview.blocks.append(overview_table(summary))
    sections.append(overview)

    summary_section = Section("Summary tables", intro=(
        "One table per surface configuration, one row per method variant. QC is the quasi-conformal distortion "
        "(1 = conformal), foldovers count flipped triangles, the exact-map error compares with the known map "
        "where the dataset has one (— where it has none)."))
    summary_section.blocks.append("<p class=\"legend\"><span class=\"swatch\">best</span> marks the best "
                                  "value of a column in its table (when at least two methods have one).</p>")
    summary_section.blocks += list(summary_tables(summary).values())
    sections.append(summary_section)

    failures = failures_table(rows)
    sections.append(Section("Failed cells", [failures if failures.rows else Note("No cell failed.", "muted")]))
    suspects = suspect_table(rows)
    if suspects.rows:
        sections.append(Section("Suspect cells", [suspects]))

    for view in picture_views(rows, results.root):
        sections.append(_view_section(results, view, warnings))

    scaling = Section("Time against size")
    picture = scaling_figure(rows)
    if picture is None:
        scaling.blocks.append(Note("No method was timed at two or more sizes of one surface: no fit.", "muted"))
    else:
        scaling.blocks += [picture, exponent_table(scaling_fits(rows))]
    memory = stage_memory_table(rows)
    if memory is not None:
        scaling.blocks.append(memory)
    sections.append(scaling)

    if stats is not None:
        bench = Section("Benchmarks", intro="From " + ", ".join(p.name for p in paths) + ".")
        picture = benchmark_figure(stats)
        if picture is not None:
            bench.blocks.append(picture)
        bench.blocks.append(benchmark_table(stats) if len(stats) else Note("The files hold no benchmark.", "muted"))
        sections.append(bench)

    run_section = Section("Run metadata", [metadata_table(results.run)])
    if warnings:
        run_section.blocks.append(Note("Skipped while reading: " + " | ".join(warnings), "warning"))
    sections.append(run_section)
    return render_report("parambench report", _subtitle(results.run, rows), sections)


def build_report(results_dir, *, benchmark_json=(), out_dir=None, formats=FORMATS) -> dict[str, Path]:
    """Write the HTML and/or PDF report of a results directory.

    Parameters
    ----------
    results_dir : str or path-like
        A directory written by ``parambench run`` (see the storage contract).
    benchmark_json : iterable of str or path-like
        pytest-benchmark JSON files (``pytest --benchmark-json=FILE``) to add.
    out_dir : str or path-like, optional
        Where to write; default ``results_dir / "report"``. Created if missing.
    formats : iterable of {"html", "pdf"}

    Returns
    -------
    dict of str to pathlib.Path
        ``{"html": .../report.html, "pdf": .../report.pdf}`` for the formats asked.

    Raises
    ------
    EmptyResultsError
        ``results_dir`` is missing or holds no finished cell.
    InputFileError
        A benchmark file is unreadable, or ``out_dir`` lies inside the package sources.
    UnknownNameError
        A format other than "html" or "pdf".
    """
    from datasets_gen.errors import UnknownNameError

    formats = tuple(formats)
    unknown = [f for f in formats if f not in FORMATS]
    if unknown:
        raise UnknownNameError(f"Unknown report format(s) {unknown}; choose from {list(FORMATS)}.")
    results = load_results(results_dir)
    out = Path(out_dir) if out_dir is not None else results.root / "report"
    _check_out_dir(out)
    text = render_html(results, benchmark_json)
    out.mkdir(parents=True, exist_ok=True)
    written: dict[str, Path] = {}
    if "html" in formats:
        path = out / "report.html"
        tmp = out / ".report.html.tmp"
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)
        written["html"] = path
    if "pdf" in formats:
        written["pdf"] = write_pdf(text, out / "report.pdf")
    return written
