"""The ``parambench`` command line: run, flatten, inspect, report, list."""

from __future__ import annotations

import argparse
import json
import re
import sys
import warnings
from contextlib import contextmanager
from pathlib import Path
from typing import Any, Sequence

from parambench.datasets_gen.errors import (REPAIR_ACTION, InputFileError, InvalidInputError, ParambenchError,
                                           ResourceLimitError)

__all__ = ["main", "parse_param_values"]

DEFAULT_OUT = "parambench-results"


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (no usage dump) and exit code 2."""

    def error(self, message: str) -> None:  # noqa: D401 - argparse API
        self.exit(2, f"parambench: error: {message} (see '{self.prog} --help')\n")


#: How a null is written on the command line (JSON's ``null`` and Python's ``None``).
NULL_WORDS = ("null", "none")


def _coerce(key: str, text: str, default: Any, nullable: bool = False) -> Any:
    if nullable and text.strip().lower() in NULL_WORDS:
        return None
    if isinstance(default, bool):
        low = text.strip().lower()
        if low in ("1", "true", "yes", "on"):
            return True
        if low in ("0", "false", "no", "off"):
            return False
        raise InvalidInputError(f"parameter {key} expects true or false, got {text!r}.")
    for kind in (int, float):
        if isinstance(default, kind):
            try:
                return kind(text)
            except ValueError:
                raise InvalidInputError(f"parameter {key} expects a {kind.__name__}, got {text!r}.") from None
    if default is None:
        try:
            return json.loads(text)
        except json.JSONDecodeError:
            return text
    return text


def parse_param_values(pairs: Sequence[str], defaults: dict, nullable: frozenset = frozenset()) -> dict:
    """Turn ``["k=1.5", "weights=uniform"]`` into typed parameters, typed like the defaults.

    ``nullable`` names parameters with a number default that also take null (``Method.nullable``,
    e.g. ``ocp``'s ``polish_spread``): ``null`` or ``none`` gives them None.

    Raises
    ------
    InvalidInputError
        A pair without ``=`` or a value of the wrong type.
    """
    params = {}
    for pair in pairs:
        if "=" not in pair:
            raise InvalidInputError(f"--param expects KEY=VALUE, got {pair!r}.")
        key, value = pair.split("=", 1)
        key = key.strip()
        params[key] = _coerce(key, value, defaults.get(key), key in nullable)
    return params


def _check_benchmark_files(paths: Sequence[str] | None) -> None:
    """Refuse missing or unreadable ``--benchmark-json`` files now rather than after the sweep."""
    missing = [p for p in paths or () if not Path(p).is_file()]
    if missing:
        raise InputFileError(f"--benchmark-json: no such file {', '.join(map(repr, missing))}; "
                             f"give files written by pytest --benchmark-json.")
    if paths:
        from parambench.reports.benchmarks import load_benchmarks

        try:
            load_benchmarks(paths)  # the report's own reader: a file that is no benchmark JSON is refused here
        except InputFileError as exc:
            raise InputFileError(f"--benchmark-json: {exc}") from None


#: A Dask scheduler address: ``host:port``, optionally with a protocol (``tcp://10.0.0.5:8786``).
_SCHEDULER_ADDRESS = re.compile(r"(?:[a-z]+://)?[^\s:/]+:\d+")


def _check_scheduler(address: str | None, workers: int | None, isolate: bool) -> None:
    """Refuse a scheduler address that is none, and options that would be ignored, before any folder is created."""
    if address is not None and not _SCHEDULER_ADDRESS.fullmatch(address):
        raise InvalidInputError(f"--scheduler: {address!r} is not a scheduler address; give host:port, e.g. "
                                "tcp://127.0.0.1:8786.")
    if address is not None and workers is not None:
        raise InvalidInputError("--workers: a local cluster's size, but --scheduler names a running cluster whose "
                                "workers run the cells; give one of the two.")
    if isolate and (address is not None or workers is not None):
        raise InvalidInputError("--isolate: runs each cell in a fresh process, one after another, to measure its "
                                "memory; it does not combine with --workers or --scheduler.")


def _cmd_run(args: argparse.Namespace) -> int:
    from .suites import check_workers, get_suite
    from .sweep import run_sweep, summary_table

    # Everything the sweep needs is checked before it creates a folder or starts a cell.
    suite = get_suite(args.suite).with_overrides(
        methods=args.methods, datasets=args.datasets, sizes=args.sizes, seeds=args.seeds,
        samplings=args.samplings, noise=args.noise)
    check_workers(args.workers)
    _check_scheduler(args.scheduler, args.workers, args.isolate)
    _check_benchmark_files(args.benchmark_json)
    if args.scheduler is not None:
        from .dask_backend import check_scheduler_reachable

        check_scheduler_reachable(args.scheduler)
    paths: dict = {}

    def report(_table) -> None:
        # Built while the sweep still holds the folder: a second sweep waiting for it (--wait)
        # started before, and wrote the same report files at the same time.
        if not args.no_report:
            from parambench.reports.build import build_report

            paths.update(build_report(args.out, benchmark_json=args.benchmark_json or ()))

    table = run_sweep(suite, args.out, scheduler=args.scheduler, workers=args.workers,
                      progress=not args.no_progress, isolate=args.isolate,
                      retry_failed=not args.keep_failed, wait=args.wait, then=report)
    print(summary_table(table))
    print(f"\nresults: {Path(args.out) / 'results.parquet'} and results.csv")
    for kind, path in paths.items():
        print(f"report ({kind}): {path}")
    return 0


def _whole_number(text: str) -> int:
    """argparse type: an integer written as one (ranges are checked with the suite)."""
    try:
        return int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None


def _at_least_three(text: str) -> int:
    value = _whole_number(text)
    if value < 3:
        raise argparse.ArgumentTypeError(f"expected a whole number of at least 3, got {text!r}")
    return value


def _number(text: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None


def _default_method(surface) -> str:
    from parambench.methods.registry import method_names

    names = method_names()
    preferred = ("scp", "scp-igl") if surface.has_faces else ("ocp",)
    for name in preferred:
        if name in names:
            return name
    raise InvalidInputError("no default method for a point set is installed; pass --method.")


#: Exit code of ``flatten`` when the map fails its self-check and ``--force`` is not given.
EXIT_SELFCHECK = 3

REPAIR_HELP = ("keep the largest connected piece (of the faces, or of the k_nn-neighbour graph for points) and "
               "repair duplicate faces, non-manifold edges and vertices (pymeshlab); for points also drop stray points "
               "off the surface (a scan's outliers); says on stderr what it dropped; the output then holds the repaired "
               "vertices, not the input's")

LAS_CLASSES_HELP = ("for a .las/.laz LiDAR file: keep only points of these ASPRS classification codes, comma-separated "
                    "(2: ground, 6: building; e.g. 2 or 2,9); rows are then the kept points in file order")


def _las_classes(text: str) -> list[int]:
    """``--las-classes``: comma-separated classification codes (0-255)."""
    return _integers(text, "classification codes", "from 0 to 255", "2 or 2,9", 0, 255)


E57_SCANS_HELP = ("for an .e57 laser-scan file: keep only these scans, 0-based indices in file order, comma-separated "
                  "(e.g. 0 or 0,2); each scan is placed by its pose; rows are then the kept scans' records, scan after "
                  "scan (a .csv keeps a nan,nan row for each record flagged invalid)")


def _e57_scans(text: str) -> list[int]:
    """``--e57-scans``: comma-separated 0-based scan indices."""
    return _integers(text, "scan indices", "from 0 (the first scan)", "0 or 0,2", 0, None)


def _integers(text: str, what: str, span: str, example: str, lowest: int, highest: int | None) -> list[int]:
    """An option's comma-separated integers, each in ``[lowest, highest]`` (no upper bound for None).

    Raises
    ------
    argparse.ArgumentTypeError
        A part that is not an integer, none given, or one out of range: the message names
        ``what`` they are, their ``span`` and an ``example``.
    """
    try:
        values = [int(part) for part in text.split(",") if part.strip()]
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: give {what} as integers, e.g. {example}") from None
    if not values or any(v < lowest or (highest is not None and v > highest) for v in values):
        raise argparse.ArgumentTypeError(f"{text!r}: {what} are integers {span}, e.g. {example}")
    return values


def _selfcheck_summary(check: dict | None) -> str:
    if not check:
        return ""
    if "n_triangles" not in check:
        return f"; self-check {'ok' if check.get('passed') else 'FAILED'}"
    turning = check.get("turning_numbers")
    cov = check.get("coverage")
    uncertain = check.get("n_flipped_uncertain", 0)
    ring = check.get("n_ring_flipped", 0)
    unresolved = check.get("n_unresolved", 0)
    return (f"; self-check {'ok' if check['passed'] else 'FAILED'}: {check.get('n_flipped', 0)} flipped"
            + (f" (+{uncertain} within the normals' error of {check.get('normal_tol_deg', 0):g} deg)" if uncertain else "")
            + (f", {ring} triangle(s) of neighbouring points reversed" if ring else "")
            + f", {check.get('n_degenerate', 0)} degenerate of {check['n_triangles']} triangles"
            + (f", boundary crosses itself in {check['n_boundary_crossings']} place(s)"
               if check.get("n_boundary_crossings") else "")
            + (f", loop turning {turning}" if turning else "")
            + (f", stretched (coherent Beltrami coefficient {check.get('coherent_beltrami', 0):.2f})"
               if "distorted" in (check.get("failed") or ()) else "")
            + (f", not conformal (coherent Beltrami coefficient {check.get('coherent_beltrami', 0):.2f}; "
               "not judged for this method)" if check.get("stretched") and not check.get("conformal_judged") else "")
            + (f", {check.get('n_outside', 0)} point(s) outside the loops"
               if "outside" in (check.get("failed") or ()) else "")
            + (f", {check['n_isolated']} point(s) far from all others" if check.get("n_isolated") else "")
            + (f", {unresolved} point(s) where the sampling does not resolve the surface (neighbouring normals "
               f"over 60 deg apart): a fold there may go unseen" if unresolved else "")
            + (f", {cov['n_uncovered']} of {cov['n_candidates']} boundary candidates off the loops"
               + ("" if cov.get("applicable", True) else " (not judged: on an irregular sampling voids look like holes)")
               if cov else "")
            + _after_error_summary(check.get("after_error"))
            + _retry_summary(check.get("retry"))
            + _kept_summary(check.get("kept")))


def _listed(note: dict) -> str:
    """A run note's changed parameters as ``key=value, ...``."""
    return ", ".join(f"{key}={value}" for key, value in note["params"].items())


def _kept_summary(kept: dict | None) -> str:
    """Which failed run's map is written when every run failed (the least doubtful one)."""
    if not kept:
        return ""
    return f"; the map kept is the least doubtful of them, the run with {_listed(kept)}"


def _after_error_summary(note: dict | None) -> str:
    """Whether the map is that of a second run after the first raised (Method.error_retry_params)."""
    if not note:
        return ""
    return f" (the map of a second run with {_listed(note)}: the first raised {note['error'].split(':', 1)[0]})"


def _retry_summary(retry: dict | None) -> str:
    """Whether the map is a retry's (Method.retry_params) and with what."""
    if not retry:
        return ""
    earlier = [_listed(note) for note in retry.get("earlier", [])]
    error = f": {retry['error']}" if retry.get("error") else ""
    if not earlier:
        if retry["passed"]:
            return f" (the map of a second run with {_listed(retry)}: the first failed, {retry['first_reason']})"
        return f" (a second run with {_listed(retry)} failed too{error})"
    n = len(earlier) + 1
    if retry["passed"]:
        return (f" (the map of retry {n} of {n}, with {_listed(retry)}: the first failed, {retry['first_reason']}; "
                f"retries with {'; with '.join(earlier)} failed)")
    return f" ({n} retries failed too: with {'; with '.join(earlier + [_listed(retry)])}{error})"


def _holes_summary(diag: dict, params: dict | None = None) -> str:
    """Whether the method filled holes to get its map, with how much, and why: asked to
    (``holes="filled"``), slots filled before the solve, or free holes that failed."""
    n = int(diag.get("holes_filled") or 0)
    if not n:
        return ""
    points = diag.get("n_fill_points")
    if (params or {}).get("holes") == "filled":
        why = "as holes=filled asks"
    elif int(diag.get("thin_holes_filled") or 0) == n:
        why = "narrow holes (slots) are filled before the solve"
    else:
        why = "with free holes the map failed"
    return f" ({n} hole(s) filled{f' with {points} points' if points else ''}: {why})"


def _angle_summary(diag: dict) -> str:
    """Whether the front end lowered the angle criterion to close a hole its loops missed."""
    angle = diag.get("boundary_angle_lowered_to")
    return f" (boundary found at {angle:g} degrees: a hole the angle asked for missed)" if angle else ""


#: ``ocp``'s first maps of its mesh fallback (``refined["first_map"]``), as the summary names them.
_FIRST_MAPS = {"sdp": "an sdp map", "unrolled boundary": "the map of its unrolled boundary",
               "plane projection": "the points' projection on a plane"}


def _energy_summary(diag: dict) -> str:
    """Whether ``ocp``'s solve fell back to the paper's energy or to a mesh of the points, or refined its map
    (a retry says so in the self-check's summary)."""
    refined = diag.get("refined") or {}
    if diag.get("energy_used") == "mesh":
        name = str(refined.get("first_map"))
        first = _FIRST_MAPS.get(name.removesuffix(", holes filled"), "a first map")
        if name.endswith(", holes filled"):
            first += " with the holes filled"
        return f" (cotangent SCP on the mesh {first} triangulates: no point-set energy's k search found a regular map)"
    if refined.get("error"):
        return f" (not refined: its uv mesh failed, {refined['error'].split(':')[0]})"
    if refined:
        return f" (refined by cotangent SCP on its own uv mesh, {refined.get('n_faces')} triangles)"
    if not diag.get("energy_error"):
        return ""
    return " (with the paper's energy: the Neumann energy's k search found no regular map)"


def _k(k_nn: Any) -> int:
    return k_nn if isinstance(k_nn, int) and k_nn > 0 else 8


def _screened(surface, k_nn: Any):
    """A point set without the normals its file's columns were only guessed to hold, where they do not fit."""
    if surface.faces is not None:
        return surface
    from .point_repair import screened_guessed_normals

    return screened_guessed_normals(surface, _k(k_nn))


_VERTICES_NOTE = "the output holds these vertices"

#: What a ``.csv`` of a repaired point set holds: it has no coordinates to match its rows to
#: the input by, so it keeps one row per input row.
_CSV_ROWS_NOTE = "the .csv has one row per input row, the {n_dropped} dropped ones nan,nan"


def _welded(surface, weld: bool):
    """``surface`` itself, or with ``--weld`` (a mesh) its coincident vertices merged; one line on stderr says so."""
    if not weld or surface.faces is None:
        return surface
    from parambench.datasets_gen.weld import weld_coincident, weld_summary

    surface, facts = weld_coincident(surface)
    print(f"parambench: note: {weld_summary(facts)}; {_VERTICES_NOTE}", file=sys.stderr)
    return surface


def _repaired(surface, repair: bool, k_nn: Any, output_note: str = _VERTICES_NOTE):
    """``surface`` itself, or with ``--repair`` its largest piece repaired, a point set's stray points dropped.

    One line on stderr says what changed, ending in ``output_note`` (what the output holds).
    """
    if not repair:
        return surface
    from parambench.datasets_gen.repair import repair_summary, repair_surface

    from .point_repair import with_usable_normals, without_stray_points

    k = _k(k_nn)
    dropped = surface.params.get("degenerate_faces_dropped", 0)
    surface, facts = repair_surface(surface, k_nn=k)
    note = repair_summary(facts) + (f"; dropped {dropped} degenerate face(s) (a repeated vertex or no area)"
                                    if dropped else "")
    if surface.faces is None and surface.n_points > k + 1:
        surface, n_stray = without_stray_points(surface, k)
        note += f"; dropped {n_stray} stray point(s) off the surface" if n_stray else ""
        surface, normals_note = with_usable_normals(surface, k)
        note += normals_note
    n_dropped = surface.params.get("file_rows", facts["points_in"]) - surface.n_points  # the reader's drops too
    is_points = surface.faces is None and "input_rows" in surface.params
    output_note = output_note.format(n_dropped=n_dropped) if is_points and n_dropped else _VERTICES_NOTE
    print(f"parambench: note: {note}; {output_note}", file=sys.stderr)
    return surface


@contextmanager
def _offer_repair(repair: bool):
    """Add ``--repair`` to the message of an error it would remove, when it was not given."""
    try:
        yield
    except ParambenchError as exc:
        if getattr(exc, "repairable", False) and not repair:
            action = getattr(exc, "repair_action", REPAIR_ACTION)
            exc.args = (f"{str(exc).rstrip('.')}; or pass --repair to {action}.",)
        raise


def _mesh_instead(surface) -> str:
    """For a point set read from a mesh file with ``--points-only``: what its faces say, else ''.

    Where they mesh an open surface without handles, to flatten them instead; where they
    mesh a closed one or one with handles, that a cut is needed (no route through the faces).
    """
    n_faces = surface.params.get("faces_dropped")
    if not n_faces:
        return ""
    topology = _dropped_faces_topology(surface.params.get("source"))
    if topology.get("boundary_loops") == 0:
        return (f"but the file's {n_faces} faces mesh a closed surface, which no method lays flat without a cut: "
                "cut it open along a seam (with a mesh editor) and flatten that")
    if (topology.get("genus") or 0) > 0:
        return (f"but the file's {n_faces} faces mesh a surface with {topology['genus']} handle(s), which no method lays "
                "flat without a cut: cut each handle open along a seam (with a mesh editor) and flatten that")
    return (f"or flatten the file's {n_faces} faces instead: leave out --points-only (a mesh method such as scp maps "
            "them where they mesh an open surface; --repair mends non-manifold parts)")


def _dropped_faces_topology(source: str | None) -> dict:
    """Boundary loops and genus of the largest piece of a file's faces; {} where it cannot be read again.

    Read again only on a failure's path: at a million faces the count takes 1-2 s.
    """
    from parambench.datasets_gen.formats import read_file
    from parambench.datasets_gen.mesh_pieces import largest_piece_topology

    try:
        raw = read_file(Path(source))
    except (ParambenchError, TypeError):
        return {}
    return largest_piece_topology(raw.faces, len(raw.points)) if raw.faces is not None and len(raw.faces) else {}


@contextmanager
def _offer_mesh(surface):
    """Add the dropped faces to the message of a point-set method's error (``--points-only``)."""
    try:
        yield
    except ParambenchError as exc:
        hint = _mesh_instead(surface)
        if hint:
            exc.args = (f"{str(exc).rstrip('.')}; {hint}.",)
        raise


@contextmanager
def _offer_more_points(keep, n_points: int):
    """Say, in a method's error on a ``--max-points`` subsample, that the subsample is what failed."""
    try:
        yield
    except ParambenchError as exc:
        if keep is not None and not isinstance(exc, ResourceLimitError):  # that one names --max-points already
            exc.args = (f"{str(exc).rstrip('.')}; {_subsample_hint(keep.size, n_points)}.",)
        raise


def _subsample_hint(n_sub: int, n_points: int) -> str:
    return (f"this is the map of the --max-points subsample ({n_sub:,} of the {n_points:,} points), sampled more "
            "coarsely than the input: raise --max-points")


def _check_output_path(out: Path, source: Path) -> None:
    """Refuse, before any work, an output that cannot be written or would overwrite the input.

    Raises
    ------
    InputFileError
        The output's folder does not exist, or the output is the input file itself (a
        mesh written over by its own uv layout, with exit code 0).
    """
    if not out.parent.exists():
        raise InputFileError(f"output directory {str(out.parent)!r} does not exist; create it first.")
    if out.exists() and source.exists() and out.resolve() == source.resolve():
        raise InputFileError(f"the output {str(out)!r} is the input file: writing it would destroy the input; "
                             "pass another output path.")


def _note_first_compilation() -> None:
    """One line on a terminal's stderr when the point-set kernels are not compiled yet (a fresh install's first use).

    Only on a terminal, as progress is: a script reading stderr gets its one error line.
    """
    if not sys.stderr.isatty():
        return
    from parambench.methods.numba_cache import cached_on_disk
    from parambench.methods.pointset.local_fits import pca_rows

    if cached_on_disk(pca_rows) is False:
        print("parambench: note: first use of this install: numba compiles the point-set kernels now (about "
              "45 s on 2 cores, once; later runs load them from its cache)", file=sys.stderr)


def _cmd_flatten(args: argparse.Namespace) -> int:
    from parambench.datasets_gen.io import load_surface
    from parambench.methods.pointset.selfcheck import coherent_limit, pointset_faces
    from parambench.methods.pointset.selfcheck_advice import failure_line
    from parambench.methods.registry import get_method

    from .uv_output import UV_FORMATS, write_uv

    out = Path(args.output)
    if out.suffix.lower() not in UV_FORMATS:
        raise InputFileError(f"cannot write {out.name!r}: output must end in {', '.join(UV_FORMATS)}.")
    _check_output_path(out, Path(args.input))
    with _offer_repair(args.repair):
        surface = _welded(load_surface(args.input, points_only=args.points_only, drop_degenerate_faces=args.repair,
                                       las_classes=args.las_classes, e57_scans=args.e57_scans), args.weld)
    method = get_method(args.method or _default_method(surface))
    if args.points_only and method.needs_faces:
        from parambench.datasets_gen.errors import MissingFacesError

        raise MissingFacesError(f"--points-only drops the faces, and method {method.name!r} needs them: leave out "
                                "--points-only, or choose a point-set method (e.g. ocp).")
    params = parse_param_values(args.param or [], method.defaults, method.nullable)
    if not method.needs_faces:
        _note_first_compilation()
    n_input_rows = surface.params.get("file_rows", surface.n_points)
    csv = out.suffix.lower() == ".csv"
    surface = _repaired(_screened(surface, params.get("k_nn", method.defaults.get("k_nn"))), args.repair,
                        params.get("k_nn", method.defaults.get("k_nn")), _CSV_ROWS_NOTE if csv else _VERTICES_NOTE)
    full, keep = surface, None
    if args.max_points is not None:
        surface, keep = _thinned(surface, args.max_points, method)
    with _offer_repair(args.repair), _offer_mesh(surface), _offer_more_points(keep, full.n_points):
        result = method(surface, **params)
    check = result.diagnostics.get("selfcheck")
    failed = check is not None and not check.get("passed", False)
    thinned = "" if keep is None else f" (a subsample of {keep.size} mapped: --max-points)"
    summary = (f"{method.name}: {full.n_points} points flattened{thinned} in {result.timings['total']:.2f} s"
               + _holes_summary(result.diagnostics, result.params) + _angle_summary(result.diagnostics)
               + _energy_summary(result.diagnostics))
    if failed and not args.force:
        print(f"{summary}{_selfcheck_summary(check)}; nothing written")
        strays = "stray" in check.get("causes", {}) or "isolated" in (check.get("failed") or ())
        repair = "--repair drops the stray points; " if strays and not args.repair else ""
        mesh = _mesh_instead(surface)
        thinned_hint = "" if keep is None else f"; {_subsample_hint(keep.size, full.n_points)}"
        print(f"parambench: error: {failure_line(check, result.params, method.name)}"
              f"{'; ' + mesh if mesh else ''}{thinned_hint} ({repair}--force writes the map anyway)", file=sys.stderr)
        return EXIT_SELFCHECK
    faces, points, uv = surface.faces, surface.points, result.uv
    if keep is not None:
        surface, points, uv, faces, spans = full, full.points, *_extended(full.points, keep, result)
        faces = None if csv else faces
        if spans["lost_hole"]:
            line = _lost_hole_line(spans, keep.size)
            if not args.force:
                print(f"{summary}{_selfcheck_summary(check)}; the full points' check FAILED: a hole lost; nothing written")
                print(f"parambench: error: {line} (--force writes the map anyway)", file=sys.stderr)
                return EXIT_SELFCHECK
            if faces is not None:  # the output shows the hole: no triangle across it
                faces = faces[~spans["spanning"]]
            left_out = "" if faces is None else f"; its {spans['n_spanning_faces']} triangles there left out"
            print(f"parambench: warning: {line} (written anyway: --force{left_out})", file=sys.stderr)
    elif faces is None and not csv:
        faces = pointset_faces(surface.points, result.uv, result.diagnostics.get("boundary_loops"))
    if csv and faces is None and "input_rows" in surface.params:
        points, uv = _in_every_input_row(surface.points, uv, surface.params["input_rows"], n_input_rows)
        if "file_rows" in surface.params and not args.repair:  # --repair's note says so already
            print(f"parambench: note: {_CSV_ROWS_NOTE.format(n_dropped=n_input_rows - surface.n_points)} "
                  "(points the file marks as empty: no return, or flagged invalid)", file=sys.stderr)
    write_uv(out, points, uv, faces)
    print(f"{summary}{_selfcheck_summary(check)} -> {out}")
    if not failed and check and check.get("stretched") and not check.get("conformal_judged"):
        print(f"parambench: note: {method.name}'s map stretches whole regions one way (coherent Beltrami coefficient "
              f"{check['coherent_beltrami']:.2f}; a conformal map stays under "
              f"{coherent_limit(check.get('normal_tol_deg')):.2g}); {method.name}'s check does not judge conformality, "
              "ocp's does (--method ocp)", file=sys.stderr)
    if failed:
        print(f"parambench: warning: {failure_line(check, result.params, method.name)} (written anyway: --force)",
              file=sys.stderr)
    return 0


def _thinned(surface, max_points: int, method):
    """``surface`` thinned to at most ``max_points`` well-spread points, and their indices (None: not thinned)."""
    if surface.faces is not None or method.needs_faces:
        raise InvalidInputError("--max-points thins a point set; for a mesh file add --points-only and a point-set "
                                "method (e.g. ocp), or leave --max-points out.")
    if surface.n_points <= max_points:
        return surface, None
    from parambench.datasets_gen.surface import Surface
    from parambench.methods.pointset.extension import thin_indices

    keep = thin_indices(surface.points, max_points)
    normals = None if surface.normals is None else surface.normals[keep]
    return Surface(points=surface.points[keep], normals=normals, name=surface.name), keep


def _extended(points, keep, result):
    """Every point's uv from the subsample's map, the subsample's triangles in ``points``' rows, and
    where they span a place the points leave empty (:func:`~parambench.methods.pointset.extension.carry_map`)."""
    from parambench.methods.pointset.extension import carry_map

    uv, faces, facts, spans = carry_map(points, keep, result.uv, result.diagnostics.get("boundary_loops"))
    off, gap = facts["offset_spacings"], spans["gap_spacings"]
    covered = "" if spans["lost_hole"] else (f"; the input covers them (every probe of them within {gap['max']:.2g} "
                                             f"local spacings of an input point, typically {gap['typical']:.2g})")
    print(f"parambench: note: the other {points.shape[0] - keep.size:,} points take the uv of their place on the "
          f"subsample's mapped triangles ({off['median']:.2g} of its edge lengths off them at the median, "
          f"{off['max']:.2g} at most; {facts['n_outside']:,} beyond its rim, carried on linearly){covered}; the "
          "output's faces are the subsample's", file=sys.stderr)
    return uv, faces, spans


def _lost_hole_line(spans: dict, n_sub: int) -> str:
    """One line for a subsample whose triangles span a hole of the input (``uncovered_spans``)."""
    gap, where = spans["gap_spacings"], ", ".join(f"{x:.6g}" for x in spans["where"])
    return (f"the subsample's map covers a place the input points leave empty ({spans['n_spanning_faces']} of its "
            f"triangles; {gap['max']:.2g} local spacings from every input point at ({where}), where this map's "
            f"triangles are typically within {gap['typical']:.2g}): a hole that thinning to {n_sub:,} points closed, "
            "mapped as surface; raise --max-points, or leave it out where the memory allows")


def _in_every_input_row(points, uv, input_rows, n_rows: int):
    """``points`` and ``uv`` spread to ``n_rows`` rows: row ``input_rows[i]`` gets row i, the others NaN."""
    import numpy as np

    rows = np.asarray(input_rows, dtype=np.int64)
    full_points, full_uv = np.full((n_rows, 3), np.nan), np.full((n_rows, 2), np.nan)
    full_points[rows], full_uv[rows] = points, uv
    return full_points, full_uv


def _in_input_rows(report: dict, input_rows) -> None:
    """Loops of a point set ``--repair`` shrank renumbered to the input file's rows, and ``input_rows`` added.

    The JSON holds no points, so indices into the repaired set (rows dropped before them
    shifted every one) could not be traced back to the file: on 3000 points with 6 junk rows
    only 10.5 % of the loop indices named boundary rows of the input.
    """
    if input_rows is None:
        return
    import numpy as np

    rows = np.asarray(input_rows, dtype=np.int64)
    report["boundary_loops"] = [rows[np.asarray(loop, dtype=np.int64)].tolist() for loop in report["boundary_loops"]]
    report["input_rows"] = rows.tolist()


def _cmd_inspect(args: argparse.Namespace) -> int:
    from dataclasses import fields

    from parambench.datasets_gen.io import load_surface
    from parambench.methods.pointset.inspect import inspect_surface
    from parambench.methods.pointset.params import FrontEndParams

    out = Path(args.output)
    if out.suffix.lower() != ".json":
        # A mistyped -o (scan.obj for scan.json) replaced a mesh with JSON, with exit 0.
        raise InputFileError(f"cannot write {out.name!r}: inspect writes JSON, so its output must end in .json.")
    _check_output_path(out, Path(args.input))
    with _offer_repair(args.repair):
        surface = load_surface(args.input, points_only=args.points_only, drop_degenerate_faces=args.repair,
                               las_classes=args.las_classes, e57_scans=args.e57_scans)
    defaults = {f.name: f.default for f in fields(FrontEndParams)}
    params = parse_param_values(args.param or [], defaults)
    unknown = sorted(set(params) - set(defaults))
    if unknown:
        from parambench.datasets_gen.errors import UnknownNameError

        raise UnknownNameError(f"unknown front-end parameter(s) {', '.join(unknown)}; accepted: {', '.join(sorted(defaults))}.")
    _note_first_compilation()
    surface = _repaired(_screened(surface, params.get("k_nn", defaults["k_nn"])), args.repair,
                        params.get("k_nn", defaults["k_nn"]))
    with _offer_repair(args.repair):
        report = inspect_surface(surface, **params)
    _in_input_rows(report, surface.params.get("input_rows"))
    out.write_text(json.dumps(report, indent=2))
    loops = report.get("boundary_loops", [])
    cov = (report.get("selfcheck") or {}).get("coverage")
    coverage = ""
    if cov:
        verdict = ("FAILED (a missed hole or boundary?)" if not cov["passed"] else "ok" if cov["applicable"]
                   else "not judged (irregular sampling: voids look like holes)")
        coverage = (f", loop coverage {verdict}: {cov['n_uncovered']} of {cov['n_candidates']} boundary "
                    f"candidates off the loops, largest connected group {cov['largest_uncovered_group']}")
    unresolved = (report.get("selfcheck") or {}).get("n_unresolved", 0)
    if unresolved:
        coverage += (f", {unresolved} point(s) where the sampling does not resolve the surface (neighbouring normals "
                     f"over 60 deg apart: a map's fold there may go unseen)")
    print(f"{surface.n_points} points, mean spacing {report['mean_spacing']:.4g}, "
          f"{len(loops)} boundary loop(s){coverage} -> {out}")
    isolated = (report.get("selfcheck") or {}).get("n_isolated", 0)
    if isolated:
        # As flatten's check says of them; before, inspect reported "coverage ok" and a mean
        # spacing of 2015 for points 0.003 apart, with exit 0.
        print(f"parambench: error: inspect: {isolated} point(s) lie far from all others (a scan's 0 0 0 rows?), and "
              f"the spacing and loops reported are skewed by them; {'remove them' if args.repair else '--repair drops them'}",
              file=sys.stderr)
        return EXIT_SELFCHECK
    handle = (report.get("selfcheck") or {}).get("handle")
    if handle:
        from parambench.methods.pointset.failure_causes import cause_advice, describe_causes

        print(f"parambench: error: inspect: {describe_causes({'handle': handle})}; "
              f"{cause_advice({'handle': handle}, [])[0]}", file=sys.stderr)
        return EXIT_SELFCHECK
    if cov and not cov["passed"]:
        # The diagnostics are written either way; the exit code says the loops are doubtful.
        from parambench.methods.pointset.selfcheck import uncovered_phrase
        from parambench.methods.pointset.selfcheck_advice import suggest_fix

        print(f"parambench: error: inspect: {uncovered_phrase(cov)} (a missed hole or boundary); "
              f"{suggest_fix(['coverage'], report['params'], 'ocp')}", file=sys.stderr)
        return EXIT_SELFCHECK
    return 0


def _check_report_out(out: str | None) -> None:
    """Refuse an ``--out`` of ``report`` that cannot be a folder before rendering anything."""
    if out is None:
        return
    path = Path(out)
    existing = path
    while not existing.exists() and existing != existing.parent:
        existing = existing.parent
    if not existing.is_dir():
        raise InputFileError(f"--out: {str(existing)!r} is a file, so {str(path)!r} cannot be the report's folder; "
                             "give a folder path.")


def _cmd_report(args: argparse.Namespace) -> int:
    _check_report_out(args.out)
    if args.other_dir:
        return _cmd_compare(args)
    from parambench.reports.build import build_report

    paths = build_report(args.results_dir, benchmark_json=args.benchmark_json or (), out_dir=args.out)
    for kind, path in paths.items():
        print(f"report ({kind}): {path}")
    return 0


def _cmd_compare(args: argparse.Namespace) -> int:
    from parambench.reports.compare import build_comparison

    if args.benchmark_json:
        raise InvalidInputError("--benchmark-json is for the report of one results directory; "
                               "drop it when comparing two (parambench report A B).")
    paths, diff = build_comparison(args.results_dir, args.other_dir, out_dir=args.out)
    regressions = diff[diff["change"] == "regression"]
    counts = diff["change"].value_counts()
    order = ("regression", "improvement", "unchanged", "only in A", "only in B")
    print(", ".join(f"{int(counts[k])} {k}" for k in order if k in counts))
    for r in regressions.head(10).itertuples():
        print(f"  REGRESSION {r.config} / {r.variant}: {r.what}")
    if len(regressions) > 10:
        print(f"  ... and {len(regressions) - 10} more regressions")
    for kind, path in paths.items():
        print(f"comparison ({kind}): {path}")
    return 0


def _cmd_list(args: argparse.Namespace) -> int:
    from parambench.datasets_gen.registry import dataset_info
    from parambench.methods.registry import all_methods

    print("methods:")
    for name, cls in all_methods().items():
        kind = "mesh" if cls.needs_faces else "points"
        print(f"  {name:<14} [{kind}] {cls.description}")
        for key, default in sorted(cls.defaults.items()):
            grid = cls.param_grid.get(key)
            extra = f"  (sweep: {', '.join(map(str, grid))})" if grid else ""
            print(f"      {key}={default!r}{extra}")
    print("\ndatasets:")
    for name, text in dataset_info().items():
        print(f"  {name:<18} {text}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    """The argument parser (exposed for documentation and tests)."""
    parser = _Parser(prog="parambench", description="Conformal parameterization of point sets and meshes, benchmarked.")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    run = sub.add_parser("run", help="run a sweep and build its report")
    run.add_argument("--suite", default="quick", help="quick (default, < 3 min), full, or scale (10k to 1M points)")
    run.add_argument("--methods", nargs="+", help="method names (default: all registered)")
    run.add_argument("--datasets", nargs="+", help="dataset names (default: the suite's)")
    run.add_argument("--sizes", nargs="+", type=_whole_number,
                     help="point counts of procedural datasets (whole numbers, at least 100)")
    run.add_argument("--seeds", nargs="+", type=_whole_number, help="seeds (whole numbers >= 0)")
    run.add_argument("--samplings", nargs="+",
                     help="grid, jittered, random, blue-noise, graded; scattered (real meshes: random points "
                          "on their triangles, none on the rim, at --sizes)")
    run.add_argument("--noise", nargs="+", type=_number,
                     help="normal noise, fraction of the mean spacing (finite, >= 0)")
    run.add_argument("--out", default=DEFAULT_OUT, help=f"results directory (default: {DEFAULT_OUT})")
    run.add_argument("--scheduler", help="address of a running Dask scheduler")
    run.add_argument("--workers", type=_whole_number, help="start a local Dask cluster with N (>= 1) workers")
    run.add_argument("--keep-failed", action="store_true",
                     help="skip cells that failed in an earlier run (default: retry them)")
    run.add_argument("--wait", action="store_true",
                     help="if another sweep is using --out, wait for it to finish (default: stop at once)")
    run.add_argument("--isolate", action="store_true",
                     help="run each cell in a fresh process and record its peak memory (scaling runs)")
    run.add_argument("--benchmark-json", nargs="+", help="pytest-benchmark JSON files to include in the report")
    run.add_argument("--no-report", action="store_true", help="skip building the report")
    run.add_argument("--no-progress", action="store_true", help="no progress bar")
    run.set_defaults(func=_cmd_run)

    flat = sub.add_parser("flatten", help="flatten a mesh or point-cloud file")
    flat.add_argument("input")
    flat.add_argument("--method", help="method name (default: scp for meshes, ocp for point sets)")
    flat.add_argument("--param", nargs="+", action="extend", metavar="KEY=VALUE", help="method parameters")
    flat.add_argument("--points-only", action="store_true", help="drop faces; treat the input as a point set")
    flat.add_argument("-o", "--output", required=True,
                      help="output .obj (v, vt, f), .ply (x y z texture_u texture_v, faces) or .csv (u,v); point sets get the "
                           "self-check's uv triangulation as faces")
    flat.add_argument("--force", action="store_true",
                      help="write a map (point set or mesh) that fails its self-check, with a warning and exit code 0 "
                           "(otherwise exit code 3, nothing written)")
    flat.add_argument("--repair", action="store_true", help=REPAIR_HELP)
    flat.add_argument("--weld", action="store_true",
                      help="merge a mesh's coincident vertices first (patches stored unwelded; not for a seam cut on "
                           "purpose); says on stderr how many; the output then holds the welded vertices")
    flat.add_argument("--las-classes", type=_las_classes, metavar="CODES", help=LAS_CLASSES_HELP)
    flat.add_argument("--e57-scans", type=_e57_scans, metavar="INDICES", help=E57_SCANS_HELP)
    flat.add_argument("--max-points", type=_at_least_three, metavar="N",
                      help="map a well-spread subsample of at most N points (one per cell of a voxel grid), then give "
                           "every other point the uv of its place on the subsample's mapped triangles: for point sets "
                           "larger than the memory holds (the output keeps every point; its faces are the subsample's); a hole "
                           "the thinning closed, where the subsample's triangles span a place with no input points, "
                           "fails the check (exit 3)")
    flat.set_defaults(func=_cmd_flatten)

    insp = sub.add_parser("inspect", help="run the point-set front end and write JSON diagnostics")
    insp.add_argument("input")
    insp.add_argument("--points-only", action="store_true", help="drop faces (the front end uses points only)")
    insp.add_argument("--param", nargs="+", action="extend", metavar="KEY=VALUE", help="front-end parameters")
    insp.add_argument("-o", "--output", required=True, help="output .json")
    insp.add_argument("--repair", action="store_true", help=REPAIR_HELP)
    insp.add_argument("--las-classes", type=_las_classes, metavar="CODES", help=LAS_CLASSES_HELP)
    insp.add_argument("--e57-scans", type=_e57_scans, metavar="INDICES", help=E57_SCANS_HELP)
    insp.set_defaults(func=_cmd_inspect)

    rep = sub.add_parser("report", help="build the HTML and PDF report of a results directory, or compare two")
    rep.add_argument("results_dir")
    rep.add_argument("other_dir", nargs="?",
                     help="a second results directory: compare it (B) with the first (A), cell by cell, "
                          "regressions first (writes compare.html)")
    rep.add_argument("--benchmark-json", nargs="+", help="pytest-benchmark JSON files")
    rep.add_argument("--out", help="output directory (default: RESULTS_DIR/report; with two: the second's report)")
    rep.set_defaults(func=_cmd_report)

    lst = sub.add_parser("list", help="list methods (with parameters) and datasets")
    lst.set_defaults(func=_cmd_list)
    return parser


def _warning_line(message, category, filename, lineno, file=None, line=None) -> None:
    # One line per warning, like errors: the source line Python would add means nothing to a user.
    print(f"parambench: warning: {category.__name__}: {message}", file=sys.stderr if file is None else file)


#: Commands that, run from the command line, end the process as soon as they are done
#: (:func:`_exit_now`): one-shot commands that leave no workers, locks or cluster behind.
FAST_EXIT_COMMANDS = frozenset({"flatten", "inspect", "list"})


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point; returns the exit code.

    2 for bad input, with one line on stderr; 3 when ``flatten`` refuses to write a
    point-set map that fails its self-check (one line on stderr saying what to try).
    Warnings (e.g. coincident points merged) are printed as one line each on stderr.

    Without ``argv`` (the process's own command line: the ``parambench`` script or
    ``python -m parambench.bench.cli``), ``flatten``, ``inspect`` and ``list`` end the
    process when done instead of returning (see :func:`_exit_now`); with ``argv`` it
    always returns.
    """
    args = build_parser().parse_args(argv)
    with warnings.catch_warnings():
        warnings.showwarning = _warning_line
        code = _dispatch(args)
    if argv is None and args.command in FAST_EXIT_COMMANDS:
        _exit_now(code)
    return code


def _exit_now(code: int) -> None:
    """End the process with ``code`` after the exit handlers, skipping the interpreter's teardown.

    Tearing down the interpreter after a point-set flatten (freeing numba's typing
    registries and compiled kernels module by module, then a last garbage collection
    over them) cost about 0.2 s of CPU, some 13 % of a 10k-point ``flatten`` (measured:
    1.76 -> 1.53 s user + sys). The output files are closed by then; the standard streams
    are flushed and the ``atexit`` handlers (logging, weakref finalizers, llvmlite's and
    numba's shutdown flags, idle worker threads) still run; only the freeing of memory
    the operating system reclaims anyway is skipped.
    """
    import atexit
    import os

    run_exit_handlers = getattr(atexit, "_run_exitfuncs", None)  # no public name for it
    if run_exit_handlers is None:  # a Python without it: the ordinary exit
        sys.exit(code)
    run_exit_handlers()  # what a normal exit runs first
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):  # a closed pipe: exit as the interpreter would (120)
            code = code or 120
    os._exit(code)


def _dispatch(args: argparse.Namespace) -> int:
    try:
        return args.func(args)
    except ParambenchError as exc:
        print(f"parambench: error: {type(exc).__name__}: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:
        # The reader of stdout left (`parambench list | head`): nothing to tell it, and the
        # interpreter's own flush at exit must not fail again (Python's documented recipe).
        import os

        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 141  # 128 + SIGPIPE, as a shell reports a pipe's writer cut short
    except OSError as exc:  # a folder the checks could not foresee (/proc as root, a disk full): one line
        print(f"parambench: error: {type(exc).__name__}: {exc}; check the path and its permissions.", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("parambench: interrupted; finished cells are kept, run again to resume.", file=sys.stderr)
        return 130


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
