"""The PDF: pages render to PNG (pdftoppm), tables are real text (pdftotext), images are embedded."""

import re
import shutil
import subprocess

import matplotlib.image
import pytest

from parambench.reports.build import build_report

pytestmark = pytest.mark.slow  # WeasyPrint takes a few seconds per report


@pytest.fixture(scope="session")
def pdf_report(built_report):
    return built_report


def pdf_text(require_tool, path, layout=True):
    args = [require_tool("pdftotext")] + (["-layout"] if layout else []) + [str(path), "-"]
    return subprocess.run(args, check=True, capture_output=True, text=True).stdout


def page_count(require_tool, path) -> int:
    info = subprocess.run([require_tool("pdfinfo"), str(path)], check=True, capture_output=True, text=True).stdout
    return int(re.search(r"^Pages:\s+(\d+)", info, flags=re.M).group(1))


def test_pdf_pages_render_to_png(pdf_report, require_tool, artifacts_dir):
    pdf = pdf_report["paths"]["pdf"]
    assert pdf.read_bytes().startswith(b"%PDF")
    n_pages = page_count(require_tool, pdf)
    # cover + tables, two surfaces with five pictures each, scaling, benchmarks, metadata
    assert 6 <= n_pages <= 20
    out = artifacts_dir / "pdf-pages"
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    subprocess.run([require_tool("pdftoppm"), "-r", "60", "-png", str(pdf), str(out / "page")], check=True)
    pages = sorted(out.glob("page-*.png"))
    assert len(pages) == n_pages
    for page in pages:
        image = matplotlib.image.imread(page)
        assert image.shape[1] > image.shape[0]  # A4 landscape
        assert (image[..., :3] < 0.9).any()  # something is printed on every page


def test_pdf_tables_are_extractable_text(pdf_report, require_tool):
    text = pdf_text(require_tool, pdf_report["paths"]["pdf"])
    for expected in ("Median QC mean per method", "Failed and suspect cells", "ConvergenceError", "Verdict", "claims",
                     "Run metadata", "0123456789abcdef", "test_ocp_2k", "Time against size", "lscm", "scp", "ocp"):
        assert expected in text, expected
    assert "OCP line search did not reach" in text
    # The overview keeps one line per method; the per-cell tables (one row per surface and
    # method, with "Seeds ok") are in the HTML only, and the PDF says where they are.
    overview_rows = [line for line in text.splitlines() if re.match(r"\s*(lscm|scp|ocp)\s+\d\.\d+\s", line)]
    assert len(overview_rows) == 3
    assert not [line for line in text.splitlines() if re.match(r"\s*(lscm|scp|ocp)\s+\d/\d\s", line)]
    assert "per-cell summary tables" in text and "report.html" in text
    html = pdf_report["paths"]["html"].read_text()
    assert html.count('<table class="summary"') == 3


def test_pdf_embeds_every_picture(pdf_report, require_tool):
    pdf = pdf_report["paths"]["pdf"]
    listing = subprocess.run([require_tool("pdfimages"), "-list", str(pdf)], check=True, capture_output=True,
                             text=True).stdout
    images = [line for line in listing.splitlines()[2:] if line.strip()]
    html = pdf_report["paths"]["html"].read_text()
    assert len(images) >= html.count("<img")


def test_pdf_of_results_that_all_failed(tmp_path, make_results, spec_type, require_tool):
    root = tmp_path / "r"
    make_results(root, spec_type(datasets={"bump": [144]}, methods=("ocp",), seeds=(0,), fail_all=True))
    paths = build_report(root, formats=("pdf",))
    assert set(paths) == {"pdf"} and not (root / "report" / "report.html").exists()
    text = pdf_text(require_tool, paths["pdf"], layout=False)
    assert "Every cell failed" in text and "ConvergenceError" in text


def test_no_page_holds_only_a_heading(pdf_report, require_tool):
    pdf = pdf_report["paths"]["pdf"]
    listing = subprocess.run([require_tool("pdfimages"), "-list", str(pdf)], check=True, capture_output=True,
                             text=True).stdout
    with_images = {int(line.split()[0]) for line in listing.splitlines()[2:] if line.strip()}
    pages = pdf_text(require_tool, pdf).split("\f")
    for number, page in enumerate(pages[: page_count(require_tool, pdf)], start=1):
        lines = [ln.strip() for ln in page.splitlines() if ln.strip()]
        body = [ln for ln in lines if not re.search(r"parambench report\s+page \d+ of \d+", ln)]
        assert number in with_images or len(body) > 2, f"page {number} holds only {body}"
