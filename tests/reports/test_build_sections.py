"""The section builders of render_html on their own, on synthetic results."""

from __future__ import annotations

import json
import re
from html import unescape

from parambench.reports import build
from parambench.reports.benchmarks import load_benchmarks
from parambench.reports.build import (_benchmark_section, _optional_sections, _problems_section, _run_section,
                           _scaling_section, _verdict_section)
from parambench.reports.html import Note, Section
from parambench.reports.labels import add_labels
from parambench.reports.load import load_results
from parambench.reports.tables import summarise


def _rows(root, make_results, spec=None):
    make_results(root, spec)
    results = load_results(root)
    rows = add_labels(results.rows)
    return results, rows, summarise(rows)


def _notes(section: Section) -> list[Note]:
    return [b for b in section.blocks if isinstance(b, Note)]


def test_verdict_section_counts_cells_and_warns_when_all_failed(tmp_path, make_results, spec_type):
    _, rows, summary = _rows(tmp_path / "some", make_results)
    verdict = _verdict_section(rows, summary)
    assert verdict.intro.startswith(f"{len(rows)} cells: {len(rows) - 1} ok, 1 failed;")
    assert not any(n.kind == "warning" for n in _notes(verdict)) and len(verdict.blocks) > 1
    _, rows, summary = _rows(tmp_path / "none", make_results, spec_type(fail_all=True))
    verdict = _verdict_section(rows, summary)
    assert [(n.text, n.kind) for n in verdict.blocks] == [
        ("Every cell failed: the tables below list the errors.", "warning")]


def test_problems_section(tmp_path, make_results, spec_type):
    _, rows, _ = _rows(tmp_path / "one", make_results)
    problems = _problems_section(rows)
    assert len(problems.blocks) == 1 and len(problems.blocks[0].rows) == 1  # the one failed cell
    _, rows, _ = _rows(tmp_path / "ok", make_results, spec_type(failed=()))
    assert [n.text for n in _notes(_problems_section(rows))] == ["No cell failed."]


def test_scaling_section_needs_a_size_curve(tmp_path, make_results, spec_type):
    results, rows, _ = _rows(tmp_path / "two", make_results)  # bump at two sizes: a curve
    scaling = _scaling_section(results.run, rows)
    assert scaling.title == "Time against size" and len(scaling.blocks) == 2  # figure and exponents
    results, rows, _ = _rows(tmp_path / "single", make_results, spec_type(datasets={"bump": [144]}))
    assert _scaling_section(results.run, rows) is None  # one size, not isolated: nothing to show


def test_optional_sections_skip_missing_parts(monkeypatch):
    monkeypatch.setattr(build, "OPTIONAL_SECTIONS", (
        ("reports.no_such_module", "part", "results"),  # not installed: silently left out
        ("parambench.reports.html", "no_such_function", "results"),  # installed, no function: a warning
        ("builtins", "len", "results"),
        ("builtins", "abs", "benchmarks"),  # other kind: not called
        ("builtins", "print", "results"),  # returns None: left out
    ))
    warnings: list[str] = []
    assert _optional_sections("results", ("abc",), warnings) == [3]
    assert warnings == ["parambench.reports.html has no no_such_function: its part of the report is left out."]


def test_benchmark_and_run_sections(tmp_path, mesh_tools):
    path = mesh_tools["write_benchmark_json"](tmp_path / "b.json")
    warnings: list[str] = []
    bench = _benchmark_section(load_benchmarks([path]), [path], warnings)
    assert bench.intro == "From b.json." and len(bench.blocks) >= 2
    run = _run_section({"suite": "quick"}, [])
    assert len(run.blocks) == 1
    run = _run_section({"suite": "quick"}, ["a", "b"])
    assert run.blocks[-1] == Note("Skipped while reading: a | b", "warning")


def test_render_html_puts_the_sections_in_order(results_dir, mesh_tools):
    bench = mesh_tools["write_benchmark_json"](results_dir.parent / "bench.json")
    html = build.render_html(load_results(results_dir), [bench])
    titles = [unescape(t) for t in re.findall(r"<h2>(.*?)</h2>", html)]
    fixed = ["Verdict: which method, where, and why", "The paper's claims, measured", "Overview",
             "Failed and suspect cells"]
    assert titles[:4] == fixed
    assert titles[-3:] == ["Time against size", "Benchmarks", "Run metadata"]
    assert all(t.startswith("Surface: ") for t in titles[4:-3]) and len(titles) > 7


def _plan(root, n_cells):
    """Record in run.json, as the sweep does before its first cell runs, how many cells it planned."""
    run_json = root / "run.json"
    run_json.write_text(json.dumps(dict(json.loads(run_json.read_text()), n_cells=n_cells)))


def test_a_partial_sweep_says_how_many_of_its_planned_cells_finished(tmp_path, make_results):
    root = tmp_path / "sweep"
    results, rows, summary = _rows(root, make_results)
    planned = len(rows)
    _plan(root, planned)
    results = load_results(root)
    assert "planned" not in build._subtitle(results.run, rows)  # every planned cell finished: nothing to say
    assert not any("planned" in n.text for n in _notes(_verdict_section(rows, summary, results.run)))

    # Interrupted before 6 cells ran and before the table was consolidated.
    for path in [root / "results.parquet", root / "results.csv", *sorted((root / "cells").glob("*.json"))[:6]]:
        path.unlink()
    results = load_results(root)
    rows = add_labels(results.rows)
    said = f"{planned - 6} of {planned} planned cells finished (the sweep was interrupted or is still running"
    assert f"{planned - 6} cells" in build._subtitle(results.run, rows) and said in build._subtitle(results.run, rows)
    warnings = [n.text for n in _notes(_verdict_section(rows, summarise(rows), results.run)) if n.kind == "warning"]
    assert len(warnings) == 1 and warnings[0].startswith(said)
