"""Page assembly: escaping, unique ids, print sizes of pictures."""

import re

import pytest

from parambench.reports.figures import Picture
from parambench.reports.html import Note, Section, print_size, render_report, render_table
from parambench.reports.tables import Cell, Table


def test_table_text_is_escaped_and_classes_kept():
    table = Table(["Method", "Value"], [[Cell("<b>x</b>", ("method",)), Cell("1 & 2", ("best",), 'say "hi"')]],
                  caption="A < B", css_class="summary", numeric={1})
    out = render_table(table)
    assert "<b>x</b>" not in out and "&lt;b&gt;x&lt;/b&gt;" in out
    assert "1 &amp; 2" in out and 'title="say &quot;hi&quot;"' in out
    assert '<td class="best num"' in out and '<table class="summary" data-sortable="1">' in out
    assert 'class="table-filter screen-only"' in out  # the filter box of an interactive table
    assert '<p class="caption">A &lt; B</p>' in out
    assert out.index("caption") < out.index("<table")


def test_ids_are_unique_and_the_contents_link_to_them():
    pic = Picture("p", "caption", "data:image/png;base64,AAAA", 500, 300)
    sections = [Section("Surface: a", [Section("uv layouts", [pic])]),
                Section("Surface: b", [Section("uv layouts", [pic]), Note("n <1>", "muted")]),
                Section("Surface: a")]
    page = render_report("T", "sub", sections)
    ids = re.findall(r'id="([^"]+)"', page)
    assert len(ids) == len(set(ids))
    assert "surface-a-uv-layouts" in ids and "surface-b-uv-layouts" in ids and "surface-a-2" in ids
    for target in re.findall(r'href="#([^"]+)"', page):
        assert target in ids
    assert '<p class="muted">n &lt;1&gt;</p>' in page
    assert page.count("img#fig-") == 2  # one print rule per picture
    assert page.count("<script>") == 1 and "src=" not in page.split("<script>")[1]  # inline, nothing fetched


@pytest.mark.parametrize("width, height, rows", [(800, 300, 1), (1500, 300, 1), (800, 900, 1), (800, 900, 3),
                                                 (300, 200, 1)])
def test_print_size_keeps_aspect_and_limits(width, height, rows):
    w, h = print_size(Picture("p", "", "", width, height, rows))
    assert w <= 1000 and h <= min(620, 215 * rows)
    assert w / h == pytest.approx(width / height, rel=0.01)
    assert w <= 0.9 * width + 1  # never enlarged beyond the screen size


def test_unknown_block_is_an_error():
    with pytest.raises(TypeError):
        render_report("T", "", [Section("s", [object()])])
