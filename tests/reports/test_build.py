"""build_report end to end on synthetic results: content, self-containment, partial results."""

import base64
import io
import re
from html import unescape
from pathlib import Path

import PIL.Image
import pytest

from parambench.datasets_gen.errors import InputFileError, UnknownNameError
from parambench.reports.build import build_report
from parambench.reports.errors import EmptyResultsError


def summary_row_count(html: str) -> int:
    tables = re.findall(r'<table class="summary"[^>]*>(.*?)</table>', html, flags=re.S)
    return sum(t.split("<tbody>", 1)[1].count("<tr") for t in tables)


def section_titles(html: str) -> list[str]:
    return [unescape(t) for t in re.findall(r"<h[23]>(.*?)</h[23]>", html)]


def test_report_has_every_part(built_report):
    html = built_report["paths"]["html"].read_text()
    rows = built_report["rows"]
    groups = {(r["dataset"], r["size"], r["method"]) for r in rows}
    assert summary_row_count(html) == len(groups) == 9
    assert html.count('<table class="summary"') == 3
    titles = section_titles(html)
    for expected in ("Overview", "Summary tables", "Failed and suspect cells", "Time against size", "Benchmarks",
                     "Run metadata", "uv layouts", "Checkerboard texture",
                     "Boundary detection, OCP landscape, Weight histograms"):
        assert expected in titles, expected
    # the verdict comes first, then the paper's claims
    assert titles[0] == "Verdict: which method, where, and why"
    assert titles[1] == "The paper's claims, measured"
    assert html.count('<table class="verdict"') == 1 and html.count('<table class="claims"') == 1
    assert "Shading rule:" in html
    # one picture section per surface family: bump (shown at its 400-point size) and saddle
    assert "Surface: bump · 400 pts · poisson (seed 0)" in titles
    assert "Surface: saddle · 144 pts · poisson (seed 0)" in titles
    assert titles.count("uv layouts") == 2
    # the failed cell is reported with its error text, in the summary and in full
    assert html.count("OCP line search did not reach turning number 1") >= 2
    assert "ConvergenceError" in html
    # best values are marked
    assert html.count('class="best') >= 9
    # run metadata and benchmark statistics
    assert "0123456789abcdef0123456789abcdef01234567" in html
    assert "testhost" in html and "test_ocp_2k" in html
    # a fitted exponent for each method appears (1.10, 1.30, 1.50)
    for text in (">1.10<", ">1.30<", ">1.50<"):
        assert text in html


def test_report_is_self_contained(built_report):
    html = built_report["paths"]["html"].read_text()
    # one inline script, no external one; nothing fetched from elsewhere
    assert html.count("<script") == 1 and "<script>" in html
    assert not re.search(r'(src|href)="(?!data:|#)', html)
    assert "fetch(" not in html and "XMLHttpRequest" not in html
    style = html.split("<style>", 1)[1].split("</style>", 1)[0]
    assert "@import" not in style and "url(" not in style
    images = re.findall(r'<img[^>]+src="data:image/(png|jpeg);base64,([^"]+)"', html)
    assert len(images) == html.count("<img") >= 10
    for kind, data in images:
        image = PIL.Image.open(io.BytesIO(base64.b64decode(data)))
        assert image.format == kind.upper() and image.size[0] > 50 and image.size[1] > 50


def test_default_out_dir_is_inside_results(tmp_path, make_results, spec_type):
    root = tmp_path / "r"
    make_results(root, spec_type(datasets={"saddle": [144]}, methods=("scp",), seeds=(0,), failed=()))
    paths = build_report(root, formats=("html",))
    assert paths == {"html": root / "report" / "report.html"}
    assert paths["html"].is_file()
    assert not (root / "report" / ".report.html.tmp").exists()
    out = build_report(root, out_dir=tmp_path / "elsewhere" / "deep", formats=("html",))
    assert out["html"] == tmp_path / "elsewhere" / "deep" / "report.html" and out["html"].is_file()


def test_out_dir_in_source_tree_is_refused(results_dir):
    source = Path(__file__).resolve().parents[2] / "reports" / "out"
    with pytest.raises(InputFileError, match="source tree"):
        build_report(results_dir, out_dir=source, formats=("html",))
    assert not source.exists()


def test_unknown_format_is_refused(results_dir):
    with pytest.raises(UnknownNameError, match="docx"):
        build_report(results_dir, formats=("docx",))


def test_empty_results_give_a_clear_message(tmp_path):
    with pytest.raises(EmptyResultsError, match="parambench run"):
        build_report(tmp_path / "nothing")
    (tmp_path / "empty" / "cells").mkdir(parents=True)
    with pytest.raises(EmptyResultsError, match="parambench run"):
        build_report(tmp_path / "empty")
    assert not (tmp_path / "empty" / "report").exists()


def test_single_method_single_dataset(tmp_path, make_results, spec_type):
    root = tmp_path / "r"
    make_results(root, spec_type(datasets={"saddle": [144]}, methods=("scp",), seeds=(0,), failed=()))
    html = build_report(root, formats=("html",))["html"].read_text()
    assert summary_row_count(html) == 1
    assert "class=\"best" not in html  # nothing to compare with
    assert "No cell failed." in html
    assert "Time against size" not in section_titles(html)  # one size: no fit, and no section for it
    assert "uv layouts" in section_titles(html)
    assert not any("OCP landscape" in t for t in section_titles(html))  # scp has no landscape


def test_all_cells_failed_still_gives_a_report(tmp_path, make_results, spec_type, mesh_tools):
    root = tmp_path / "r"
    make_results(root, spec_type(datasets={"bump": [144]}, methods=("ocp", "scp"), seeds=(0, 1), fail_all=True))
    html = build_report(root, formats=("html",))["html"].read_text()
    assert "Every cell failed" in html
    assert summary_row_count(html) == 2
    failures = re.search(r'<table class="failures"[^>]*>(.*?)</table>', html, flags=re.S).group(1)
    assert failures.count("<tr") == 1 + 1  # header + the one message, shared by the four failed cells
    assert ">4</td>" in failures
    assert "No method stored uv arrays" in html
    assert any("Weight histograms" in t for t in section_titles(html))  # the surface's own diagnostics remain


def test_missing_arrays_and_unreadable_files_are_noted(tmp_path, make_results, spec_type):
    root = tmp_path / "r"
    make_results(root, spec_type(datasets={"bump": [144]}, seeds=(0,), failed=(), parquet=False, run_json=False))
    npz = sorted((root / "cells").glob("*lscm*.npz"))[0]
    npz.unlink()  # big cells keep no arrays
    bad = sorted((root / "cells").glob("*scp*.npz"))[0]
    bad.write_bytes(b"garbage")
    # A truncated zip (an interrupted copy) raised BadZipFile, which stopped the report.
    cut = sorted((root / "datasets").glob("*.npz"))[0]
    cut.write_bytes(cut.read_bytes()[:1000])
    html = build_report(root, formats=("html",))["html"].read_text()
    assert "lscm (no stored arrays)" in html
    assert "no picture from" in html and bad.name in html and cut.name in html
    assert "run.json is missing" in html
    assert "uv layouts" in section_titles(html)  # ocp still drawn


def test_bad_benchmark_file_is_a_clear_error(results_dir, tmp_path):
    bad = tmp_path / "bench.json"
    bad.write_text("{}")
    with pytest.raises(InputFileError, match="benchmark-json"):
        build_report(results_dir, benchmark_json=[bad], formats=("html",))


def test_memory_table_only_for_isolated_runs(tmp_path, make_results, spec_type):
    import json

    root = tmp_path / "r"
    make_results(root, spec_type(datasets={"bump": [144, 400]}, methods=("scp",), seeds=(0,), failed=(),
                                 parquet=False))
    for path in (root / "cells").glob("*.json"):
        row = json.loads(path.read_text())
        row["stage_memory_mb"] = json.dumps({"solve": 812.0, "knn": 700.0})
        path.write_text(json.dumps(row))
    html = build_report(root, formats=("html",))["html"].read_text()
    assert "Peak resident memory" not in html  # whole-process figures of an in-process sweep say little
    run = json.loads((root / "run.json").read_text())
    run["command"] = "parambench run --suite scale --isolate"
    (root / "run.json").write_text(json.dumps(run))
    html = build_report(root, formats=("html",))["html"].read_text()
    assert "Peak resident memory" in html and ">812<" in html


def test_optional_sections_are_added_when_their_module_exists(tmp_path, make_results, spec_type, monkeypatch,
                                                              mesh_tools):
    import sys
    import types

    from parambench.reports import build
    from parambench.reports.html import Note, Section

    root = tmp_path / "r"
    make_results(root, spec_type(datasets={"saddle": [144]}, methods=("scp",), seeds=(0,), failed=()))
    module = types.ModuleType("reports_test_extra")
    module.report_section = lambda results, rows: Section("Extra section", [Note(f"{len(rows)} rows seen")])
    module.bench_section = lambda stats: Section("Extra benchmark part", [Note(f"{len(stats)} benchmarks seen")])
    monkeypatch.setitem(sys.modules, "reports_test_extra", module)
    monkeypatch.setattr(build, "OPTIONAL_SECTIONS", (
        ("reports_test_extra", "report_section", "results"), ("reports_test_extra", "bench_section", "benchmarks"),
        ("reports_not_installed_module", "section", "results")))
    html = build_report(root, formats=("html",))["html"].read_text()
    assert "Extra section" in section_titles(html) and "1 rows seen" in html
    assert "Extra benchmark part" not in section_titles(html)  # no benchmark file: not called
    bench = mesh_tools["write_benchmark_json"](tmp_path / "bench.json")
    html = build_report(root, benchmark_json=[bench], formats=("html",))["html"].read_text()
    assert "Extra benchmark part" in section_titles(html) and "3 benchmarks seen" in html


def test_angle_histograms_join_the_surface_row_when_stored(tmp_path, make_results, spec_type, monkeypatch):
    import json
    import sys
    import types

    import numpy as np

    from parambench.reports import build
    from parambench.reports.figures._common import figure_to_picture, new_figure

    root = tmp_path / "r"
    make_results(root, spec_type(datasets={"saddle": [144]}, methods=("scp", "lscm"), seeds=(0,), failed=(),
                                 parquet=False))
    html = build_report(root, formats=("html",))["html"].read_text()
    assert not any("Angle distortion" in t for t in section_titles(html))  # no angle_hist column: no picture
    for path in (root / "cells").glob("*.json"):
        row = json.loads(path.read_text())
        row["angle_hist"] = json.dumps([1, 5, 1])
        path.write_text(json.dumps(row))
    seen = {}

    def figure(histograms, edges, title):
        seen["labels"], seen["edges"] = sorted(label for label, _ in histograms), list(edges)
        fig = new_figure(3, 2)
        fig.subplots().plot([0, 1])
        return figure_to_picture(fig, f"Angle distortion — {title}")

    module = types.ModuleType("reports_test_angles")
    module.angle_histogram_figure = figure
    monkeypatch.setitem(sys.modules, "reports_test_angles", module)
    monkeypatch.setattr(build, "ANGLE_HISTOGRAM", ("reports_test_angles", "angle_histogram_figure"))
    # the report passes on the schema's bin edges, whatever they are
    monkeypatch.setattr(build, "ANGLE_HIST_EDGES_DEG", np.array([-1.0, 0.0, 1.0, 2.0]))
    html = build_report(root, formats=("html",))["html"].read_text()
    assert any("Angle distortion" in t for t in section_titles(html))
    assert seen == {"labels": ["lscm", "scp"], "edges": [-1.0, 0.0, 1.0, 2.0]}
