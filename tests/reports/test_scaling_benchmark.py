"""The scaling benchmark's side-by-side report section, fed a small synthetic benchmark JSON."""

from __future__ import annotations

import json

import pytest

from parambench.reports.benchmarks import load_benchmarks
from parambench.reports.build import _benchmark_section
from parambench.reports.html import render_table
from parambench.reports.scaling_benchmark import (METHOD_KEY, scaling_benchmark_rows, scaling_benchmark_section,
                                                  scaling_benchmark_table)


def _run(method, n, seconds, ratio, stages):
    info = {METHOD_KEY: method, "n_points": n, "time_ratio_vs_scp_igl": ratio,
            "stage_timings": {name: sec for name, sec, _ in stages},
            "stage_peak_rss_mb": {name: mb for name, _, mb in stages if mb is not None},
            "peak_rss_mb": max(mb or 0 for _, _, mb in stages)}
    return {"group": f"scaling-{n}", "name": f"test_scaling_bump[{n}-{method}]", "extra_info": info,
            "stats": {"min": seconds, "max": seconds, "mean": seconds, "stddev": 0.0, "median": seconds, "rounds": 1}}


@pytest.fixture
def stats(tmp_path, mesh_tools):
    runs = [_run("scp-igl", 1_000_000, 300.0, 1.0, [("solve", 300.0, 10240.0)]),
            _run("ocp-multilevel", 1_000_000, 51.0, 0.17, [("knn", 2.0, 900.0), ("solve", 16.0, 2867.2)]),
            _run("ocp", 10_000, 0.5, 2.5, [("knn", 0.1, None), ("solve", 0.3, 200.0)])]
    path = tmp_path / "scaling.json"
    path.write_text(json.dumps({"benchmarks": runs}))
    other = mesh_tools["write_benchmark_json"](tmp_path / "other.json")  # no scaling runs in it
    return load_benchmarks([path, other])


def test_rows_pick_the_scaling_runs_sorted_by_size_then_time(stats):
    rows = scaling_benchmark_rows(stats)
    assert list(zip(rows["n_points"], rows["method"])) == [(10_000, "ocp"), (1_000_000, "ocp-multilevel"),
                                                           (1_000_000, "scp-igl")]
    ml = rows.iloc[1]
    assert ml["seconds"] == 51.0 and ml["time_ratio_vs_scp_igl"] == 0.17 and ml["peak_rss_mb"] == 2867.2
    assert ml["stages"] == [("knn", 2.0, 900.0), ("solve", 16.0, 2867.2)]
    knn = rows.iloc[0]["stages"][0]
    assert knn[:2] == ("knn", 0.1) and knn[2] != knn[2]  # no peak stored: NaN


def test_table_shows_stages_in_gigabytes(stats):
    table = scaling_benchmark_table(stats)
    col = {name: i for i, name in enumerate(table.columns)}
    ml = table.rows[1]
    assert ml[col["Method"]].text == "ocp-multilevel" and ml[col["Time / scp-igl"]].text == "0.17"
    assert ml[col["Peak RSS (GB)"]].text == "2.8"
    assert ml[col["Stages: seconds, peak RSS"]].text == "knn 2 s, 0.879 GB; solve 16 s, 2.8 GB"
    assert table.rows[0][col["Stages: seconds, peak RSS"]].text == "knn 0.1 s; solve 0.3 s, 0.195 GB"
    assert render_table(table).count("<tr>") == 4


def test_section_is_in_the_benchmarks_part_only_when_there_are_scaling_runs(stats, tmp_path, mesh_tools):
    section = scaling_benchmark_section(stats)
    assert "3 run(s) at 10000, 1000000 points" in section.blocks[0].text
    bench = _benchmark_section(stats, [tmp_path / "scaling.json"], [])
    assert section.title in [getattr(block, "title", None) for block in bench.blocks]
    other = load_benchmarks([mesh_tools["write_benchmark_json"](tmp_path / "other2.json")])
    assert scaling_benchmark_section(other) is None and scaling_benchmark_section(None) is None
    assert scaling_benchmark_rows(other).empty
