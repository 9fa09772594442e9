"""Build the HTML and PDF report of a results directory.

The report only reads what the sweep stored (rows, npz arrays, run metadata, optional
pytest-benchmark files); it never runs a method. Missing pieces (no arrays for big cells,
no dataset diagnostics, no landscape, a single size) leave their picture out with a note,
and failed cells are reported, not dropped.
"""

from __future__ import annotations

import importlib
from pathlib import Path

import numpy as np
import pandas as pd

from parambench.bench.schema import ANGLE_HIST_EDGES_DEG
from parambench.bench.storage import atomic_write_bytes
from parambench.datasets_gen.errors import InputFileError

from .benchmarks import load_benchmarks
from .errors import EmptyResultsError
from .claims import check_claims, claims_table, sdp_size_curve
from .peers import claim_ocp_vs_fbcp, ocp_vs_fbcp_table
from .figures import (BoundaryPanel, LandscapeCurve, LayoutPanel, benchmark_figure, boundary_figure,
                      checkerboard_figure, landscape_figure, scaling_figure, scaling_fits, sdp_curve_figure,
                      uv_layout_figure, weights_figure)
from .html import Note, Row, Section, render_report
from .labels import add_labels
from .map_groups import SAME_MAP_TOLERANCE, MapGroup, group_maps
from .load import CellArrays, Results, load_cell_arrays, load_dataset_arrays, load_results
from .pdf import write_pdf
from .selection import PictureView, dataset_npz_candidates, picture_views
from .tables import (ACCEPTABLE_RULE, MEASURED_STATUSES, benchmark_table, exponent_table, failures_table,
                     metadata_table, overview_table, stage_memory_table, summarise, summary_tables, suspect_table)
from .verdict import family_verdicts, verdict_sentences, verdict_table

__all__ = ["build_report", "render_html", "check_out_dir", "EmptyResultsError", "FORMATS", "OPTIONAL_SECTIONS",
           "ANGLE_HISTOGRAM"]

FORMATS = ("html", "pdf")
_SOURCE_PACKAGES = ("methods", "datasets_gen", "bench", "reports", "tests")
_MAX_BOUNDARY_PANELS = 6
#: Printed height of the per-surface uv and checkerboard figures together (CSS px), and the
#: most per row of panels: with the heading, a note and the row of small diagnostics they
#: fill one A4 landscape page (about 695 px of text height) and do not spill over.
_SURFACE_FIGURES_PX = 360
_SURFACE_ROW_MAX_PX = 150
_SMALL_ROW_PX = 112

#: Sections other modules may add, as (module, function, input): a module that is not
#: installed is skipped. ``input`` says what the function is called with: "results" ->
#: ``function(results, rows)`` (the loaded :class:`~parambench.reports.load.Results` and the labelled
#: rows), placed after the per-surface pages; "benchmarks" -> ``function(stats)`` (the
#: pytest-benchmark statistics, only when benchmark files were given), placed in the
#: Benchmarks section. Each returns a :class:`~parambench.reports.html.Section` or None (no data).
OPTIONAL_SECTIONS = (
    ("parambench.reports.boundary_benchmark", "boundary_benchmark_section", "benchmarks"),
    ("parambench.reports.scaling_benchmark", "scaling_benchmark_section", "benchmarks"),
)
#: A per-surface picture other modules may add to the row of small figures: (module,
#: function); called as ``function(histograms, edges, title)`` with each drawn variant's
#: stored ``angle_hist`` and the bin edges of ``parambench.bench.schema.ANGLE_HIST_EDGES_DEG``.
ANGLE_HISTOGRAM = ("parambench.reports.figures.angle_histogram", "angle_histogram_figure")


def check_out_dir(out_dir: Path) -> None:
    """Refuse an output folder inside the package sources (raises InputFileError)."""
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
    section = Section(f"Surface: {view.title}", new_page=True, css_class="surface")
    panels: list[LayoutPanel] = []
    not_drawn: list[str] = []
    cell_arrays: dict[str, CellArrays] = {}
    statuses: dict[str, str] = {}
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
        statuses[row.variant] = row.status

    try:
        surface = load_dataset_arrays(results.root, dataset_npz_candidates(view))
    except InputFileError as exc:
        warnings.append(str(exc))
        surface = None

    if panels:
        groups = group_maps([p.label for p in panels], [p.arrays.points for p in panels],
                            [p.arrays.uv for p in panels],
                            keys=[(int(p.arrays.flipped.sum()), statuses[p.label]) for p in panels])
        drawn = [_group_panel(group, panels) for group in groups]
        layouts = uv_layout_figure(drawn, view.title)
        checks = checkerboard_figure([(p.label, p.arrays) for p in drawn], view.title)
        # Both figures share the page with a row of small ones: rows shrink as they multiply.
        row_px = min(_SURFACE_ROW_MAX_PX, _SURFACE_FIGURES_PX // max(1, layouts.rows + checks.rows))
        for picture in (layouts, checks):
            picture.config, picture.print_row_px = view.config, row_px
            _alias_panels(picture, groups)
        section.blocks.append(Section("uv layouts", [layouts]))
        section.blocks.append(Section("Checkerboard texture", [checks]))
        shared = [g for g in groups if len(g.members) > 1]
        if shared:
            section.blocks.append(Note(
                "Drawn once, near-identical maps (uv equal up to rotation, reflection and scale within "
                f"{100 * SAME_MAP_TOLERANCE:g} % of the map's size, same foldovers and status): "
                + "; ".join(" = ".join(g.members) for g in shared) + ".", "muted"))
    else:
        section.blocks.append(Note("No method stored uv arrays for this surface, so there are no layout "
                                   "pictures (cells above the artifact size limit store none).", "muted"))
    if not_drawn:
        section.blocks.append(Note("Not drawn: " + "; ".join(not_drawn) + ".", "muted"))

    # Boundary, landscape and weights are small: one row under the two big figures.
    small = []
    boundary = _boundary_panels(view, surface, cell_arrays)
    if boundary:
        small.append(boundary_figure(boundary, view.title))

    curves = []
    for row in view.rows.itertuples():
        arrays = cell_arrays.get(row.variant)
        if arrays is not None and arrays.landscape is not None and len(arrays.landscape["k"]):
            land = arrays.landscape
            curves.append(LandscapeCurve(row.variant, land["k"], land["E"], land["t"], row.k_opt))
    if curves:
        small.append(landscape_figure(curves, view.title))

    if surface is not None:
        picture = weights_figure(surface, view.title)
        if picture is not None:
            small.append(picture)
    picture = _angle_histogram(view, [p.label for p in panels], warnings)
    if picture is not None:
        small.append(picture)
    if small:
        names = {"Boundary": "Boundary detection", "OCP": "OCP landscape", "Weight": "Weight histograms",
                 "Angle": "Angle distortion"}
        title = ", ".join(next((v for k, v in names.items() if p.title.startswith(k)), p.title.split(" — ")[0])
                          for p in small)
        section.blocks.append(Section(title, [Row(small, row_height=_SMALL_ROW_PX)]))
    return section


def _group_panel(group: MapGroup, panels: list[LayoutPanel]) -> LayoutPanel:
    """The panel drawn for a group: its first map, titled with every member and their QC range."""
    first = panels[group.indices[0]]
    qc = [panels[i].qc_mean for i in group.indices if panels[i].qc_mean == panels[i].qc_mean]
    if len(group.members) == 1 or not qc:
        return first
    return LayoutPanel(group.label(), first.arrays, min(qc), first.foldovers, max(qc))


def _alias_panels(picture, groups: list[MapGroup]) -> None:
    """Point every member of a group at the group's panel, for the detail view."""
    for group in groups:
        if len(group.members) > 1:
            box = picture.panels.pop(group.label(), None)
            if box is not None:
                picture.panels.update({member: box for member in group.members})


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
    # Methods that share the front end detect the same loops: one panel per distinct detection.
    seen = {_loops_key(panels[0].det_loops)} if panels and panels[0].det_loops is not None else set()
    by_key: dict = {}
    for variant, arrays in cell_arrays.items():
        if arrays.det_loops is None:
            continue
        key = _loops_key(arrays.det_loops)
        if key in seen:
            continue
        if key in by_key:
            by_key[key].label += f", {variant}"
            continue
        gt = arrays.gt_loops
        if gt is None and surface is not None and len(surface.get("points", ())) == len(arrays.points):
            gt = surface_gt
        by_key[key] = BoundaryPanel(variant, arrays.points, gt, None, arrays.det_loops, arrays.faces)
    panels += list(by_key.values())
    return panels[:_MAX_BOUNDARY_PANELS]


def _loops_key(loops) -> tuple:
    return tuple(sorted(tuple(int(i) for i in np.sort(np.asarray(loop))) for loop in loops or []))


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
    unfinished = _unfinished(run, rows)
    if unfinished:
        parts.append(unfinished)
    return " · ".join(parts)


def _unfinished(run: dict, rows: pd.DataFrame) -> str:
    """The line "k of N planned cells finished (…)" when the run planned more cells than there are rows, else "".

    A report of an interrupted or still running sweep must not read as the whole sweep: the
    planned count is ``run.json``'s ``n_cells``, written before the first cell runs.
    """
    planned = run.get("n_cells")
    if isinstance(planned, bool) or not isinstance(planned, (int, float)) or not planned == planned:
        return ""
    if len(rows) >= planned:
        return ""
    return (f"{len(rows)} of {int(planned)} planned cells finished (the sweep was interrupted or is still "
            f"running: this report is incomplete)")


def render_html(results: Results, benchmark_json=()) -> str:
    """The report page for loaded results.

    Parameters
    ----------
    results : Results
        From :func:`parambench.reports.load.load_results`.
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
    sections = [_verdict_section(rows, summary, results.run), _claims_section(rows),
                _overview_section(summary), _problems_section(rows)]
    # In this order: the surface pages and the optional parts add to ``warnings``, which
    # the run metadata section at the end lists.
    sections += [_view_section(results, view, warnings) for view in picture_views(rows, results.root)]
    sections += _optional_sections("results", (results, rows), warnings)
    scaling = _scaling_section(results.run, rows)
    if scaling is not None:
        sections.append(scaling)
    if stats is not None:
        sections.append(_benchmark_section(stats, paths, warnings))
    sections.append(_run_section(results.run, warnings))
    return render_report("parambench report", _subtitle(results.run, rows), sections)


def _verdict_section(rows: pd.DataFrame, summary: pd.DataFrame, run: dict | None = None) -> Section:
    """Cell counts, the verdict sentences and the verdict table (a warning instead when every cell failed).

    ``run`` (``run.json``) gives the planned number of cells: a partial sweep is said to be one, first.
    """
    n_ok, n_suspect = int((rows["status"] == "ok").sum()), int((rows["status"] == "suspect").sum())
    verdicts = family_verdicts(summary, rows)
    verdict = Section("Verdict: which method, where, and why", intro=(
        f"{len(rows)} cells: {n_ok} ok, " + (f"{n_suspect} suspect (map failed its self-check), " if n_suspect else "")
        + f"{len(rows) - n_ok - n_suspect} failed; {rows['variant'].nunique()} method variant(s) on "
        f"{rows['config'].nunique()} surface configuration(s). Every sentence and cell below is computed from this "
        f"run's results."))
    unfinished = _unfinished(run or {}, rows)
    if unfinished:
        verdict.blocks.append(Note(unfinished[0].upper() + unfinished[1:] + ".", "warning"))
    if n_ok + n_suspect == 0:
        verdict.blocks.append(Note("Every cell failed: the tables below list the errors.", "warning"))
    else:
        verdict.blocks += [Note(text) for text in verdict_sentences(verdicts)]
        table = verdict_table(verdicts)
        table.note = ACCEPTABLE_RULE
        verdict.blocks.append(table)
    return verdict


def _claims_section(rows: pd.DataFrame) -> Section:
    """The paper's claims table and the suite's goal against fbcp-pc, with the SDP-against-N
    curve and the per-surface ocp / fbcp-pc table when the run has them."""
    claims = Section("The paper's claims, measured", [claims_table([*check_claims(rows), *claim_ocp_vs_fbcp(rows)])])
    picture = sdp_curve_figure(sdp_size_curve(rows))
    if picture is not None:
        claims.blocks.append(Section("SDP against N on surfaces with holes", [picture]))
    peers = ocp_vs_fbcp_table(rows)
    if peers is not None:
        claims.blocks.append(Section("ocp against fbcp-pc, surface by surface", [peers]))
    return claims


def _overview_section(summary: pd.DataFrame) -> Section:
    """The overview table and the per-configuration summary tables (HTML only)."""
    overview = Section("Overview", intro=(
        "Values are medians over seeds; every metric is lower-is-better. Click a header to sort, a summary row to "
        "see that cell's pictures. The surface pages after the tables show, per surface: uv layouts coloured by "
        "per-triangle QC on one scale (foldovers red); a checkerboard mapped onto the surface through each uv "
        "(square checks = angle-preserving, about 20 across), near-identical maps drawn once in a panel that names "
        "them all; and a row with the detected boundary against the truth (one panel per distinct detection), the k "
        "line search and the weight histograms."))
    table = overview_table(summary)
    table.note = ACCEPTABLE_RULE
    overview.blocks.append(table)
    summary_blocks = list(summary_tables(summary).values())
    if summary_blocks:
        summary_blocks[-1].note = ACCEPTABLE_RULE
    # One row per cell: long for a printed page (a page per surface at 19 variants), so the
    # PDF keeps the overview above and points to the HTML, which can sort and filter them.
    overview.blocks.append(Section("Summary tables", summary_blocks, css_class="screen-only", intro=(
        "One table per surface configuration, one row per method variant. QC is the quasi-conformal distortion "
        "(1 = conformal), foldovers count flipped triangles, the exact-map error compares with the known map "
        "where the dataset has one (— where it has none).")))
    overview.blocks.append(Note(
        "The per-cell summary tables (QC mean, p95 and max, foldovers, area distortion, exact-map error, time and "
        "status of every method on every surface) are in the HTML report (report.html), where they sort, filter "
        "and open each cell's pictures.", "muted print-only"))
    return overview


def _problems_section(rows: pd.DataFrame) -> Section:
    """The failed cells (or a note that none failed) and the suspect ones."""
    failures = failures_table(rows)
    suspects = suspect_table(rows)
    problems = Section("Failed and suspect cells")
    problems.blocks.append(failures if failures.rows else Note("No cell failed.", "muted"))
    if suspects.rows:
        problems.blocks.append(suspects)
    return problems


def _optional_sections(kind: str, args: tuple, warnings: list[str]) -> list:
    """What the installed :data:`OPTIONAL_SECTIONS` of this kind return for ``args`` (None results left out)."""
    out = []
    for module_name, function_name, part_kind in OPTIONAL_SECTIONS:
        function = _optional_function(module_name, function_name, warnings)
        extra = function(*args) if function is not None and part_kind == kind else None
        if extra is not None:
            out.append(extra)
    return out


def _scaling_section(run: dict, rows: pd.DataFrame) -> Section | None:
    """Time against size with the fitted exponents, and memory per stage when cells ran isolated; None if neither."""
    picture = scaling_figure(rows)
    memory = stage_memory_table(rows) if _isolated(run) else None
    if picture is None and memory is None:
        return None
    scaling = Section("Time against size")
    if picture is not None:
        scaling.blocks += [picture, exponent_table(scaling_fits(rows))]
    if memory is not None:
        scaling.blocks.append(memory)
    return scaling


def _benchmark_section(stats: pd.DataFrame, paths: list[Path], warnings: list[str]) -> Section:
    """The pytest-benchmark figure and table, and the optional benchmark parts."""
    bench = Section("Benchmarks", intro="From " + ", ".join(p.name for p in paths) + ".")
    picture = benchmark_figure(stats)
    if picture is not None:
        bench.blocks.append(picture)
    bench.blocks.append(benchmark_table(stats) if len(stats) else Note("The files hold no benchmark.", "muted"))
    bench.blocks += _optional_sections("benchmarks", (stats,), warnings)
    return bench


def _run_section(run: dict, warnings: list[str]) -> Section:
    """Run metadata, and what was skipped while reading."""
    run_section = Section("Run metadata", [metadata_table(run)])
    if warnings:
        run_section.blocks.append(Note("Skipped while reading: " + " | ".join(warnings), "warning"))
    return run_section


def _isolated(run: dict) -> bool:
    """Whether the run measured each cell in its own process (only then is memory per cell)."""
    params = run.get("parameters") if isinstance(run.get("parameters"), dict) else {}
    return bool(run.get("isolate") or params.get("isolate") or "--isolate" in str(run.get("command", "")))


def _optional_function(module_name: str, function_name: str, warnings: list[str]):
    """``module_name.function_name``, or None when the module is not installed."""
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name and module_name.startswith(exc.name):
            return None  # not installed: the part is optional
        raise
    function = getattr(module, function_name, None)
    if function is None:
        warnings.append(f"{module_name} has no {function_name}: its part of the report is left out.")
    return function


def _angle_histogram(view: PictureView, drawn: list[str], warnings: list[str]):
    if "angle_hist" not in view.rows.columns:
        return None  # results stored before the column existed
    function = _optional_function(*ANGLE_HISTOGRAM, warnings)
    if function is None:
        return None
    rows = view.rows[view.rows["variant"].isin(drawn)]
    # The schema gives every row the column; rows stored without a histogram leave it empty.
    rows = rows[rows["angle_hist"].map(lambda h: h is not None and not (isinstance(h, float) and h != h)
                                       and len(h) > 0)]
    if rows.empty:
        return None
    try:
        return function(list(zip(rows["variant"], rows["angle_hist"])), ANGLE_HIST_EDGES_DEG, view.title)
    except ValueError as exc:  # histograms stored over other edges
        warnings.append(f"no angle histogram for {view.title}: {exc}")
        return None


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
    from parambench.datasets_gen.errors import UnknownNameError

    formats = tuple(formats)
    unknown = [f for f in formats if f not in FORMATS]
    if unknown:
        raise UnknownNameError(f"Unknown report format(s) {unknown}; choose from {list(FORMATS)}.")
    results = load_results(results_dir)
    out = Path(out_dir) if out_dir is not None else results.root / "report"
    check_out_dir(out)
    text = render_html(results, benchmark_json)
    out.mkdir(parents=True, exist_ok=True)
    written: dict[str, Path] = {}
    if "html" in formats:
        path = out / "report.html"
        atomic_write_bytes(path, text.encode("utf-8"))
        written["html"] = path
    if "pdf" in formats:
        written["pdf"] = write_pdf(text, out / "report.pdf")
    return written
