"""Assemble the report as one self-contained HTML page.

Images are PNG or JPEG data URIs, the style sheet and a small script are inline, there is no
external request or font, so the file opens offline and prints the same. The script
(:mod:`parambench.reports.interactive`) makes tables sortable and filterable and opens a cell's
pictures on a click; WeasyPrint ignores it. The same page feeds WeasyPrint for the PDF:
print rules (``@page``, page breaks) sit in the same style sheet.
"""

from __future__ import annotations

import html
import json
import re
from dataclasses import dataclass, field

from .figures import Picture
from .interactive import SCRIPT, STYLE as INTERACTIVE_STYLE
from .tables import Table

__all__ = ["Note", "Section", "Row", "render_table", "render_picture", "render_report", "anchor", "print_size"]


@dataclass
class Note:
    """A paragraph of text; ``kind`` is a CSS class ("", "warning", "muted")."""

    text: str
    kind: str = ""


@dataclass
class Row:
    """Small pictures side by side (each printed at ``1/len(pictures)`` of the text width).

    ``row_height`` is the printed height limit in CSS px.
    """

    pictures: list
    row_height: int = 170


@dataclass
class Section:
    """A titled part of the report; blocks are Tables, Pictures, Notes or sub-Sections.

    ``new_page`` starts the section on a new page in print; ``css_class`` is added to the
    ``<section>`` element (print rules select on it).
    """

    title: str
    blocks: list = field(default_factory=list)
    intro: str = ""
    new_page: bool = False
    css_class: str = ""


_STYLE = """
@page { size: A4 landscape; margin: 12mm 12mm 14mm 12mm;
        @bottom-right { content: "page " counter(page) " of " counter(pages); font-size: 8pt; color: #777; }
        @bottom-left { content: "parambench report"; font-size: 8pt; color: #777; } }
html { font-family: "DejaVu Sans", "Liberation Sans", Arial, Helvetica, sans-serif; color: #222; }
body { margin: 0 auto; padding: 1.2em 2em 3em; max-width: 1250px; font-size: 10.5pt; line-height: 1.4; }
h1 { font-size: 20pt; margin: 0 0 0.2em; color: #1b3a5c; }
h2 { font-size: 15pt; margin: 1.6em 0 0.5em; padding-bottom: 0.15em; border-bottom: 2px solid #1b3a5c;
     color: #1b3a5c; }
h3 { font-size: 12pt; margin: 1.2em 0 0.4em; color: #244a73; }
p.subtitle { color: #555; margin-top: 0; }
p.warning { background: #fff4e5; border-left: 4px solid #f28e2b; padding: 0.4em 0.8em; }
p.muted { color: #666; font-style: italic; }
nav.toc { background: #f4f6f9; border: 1px solid #dde3ea; padding: 0.5em 1.2em; margin: 1em 0; }
nav.toc ol { margin: 0.2em 0; padding-left: 1.4em; columns: 2; }
nav.toc a { color: #1b3a5c; text-decoration: none; }
table { border-collapse: collapse; margin: 0.4em 0 1.2em; font-size: 9pt; width: auto; max-width: 100%; }
p.caption { font-weight: bold; margin: 0.8em 0 0.3em; color: #333; }
div.table > table { margin-top: 0; }
th, td { border: 1px solid #d4d9e0; padding: 0.22em 0.5em; vertical-align: top; text-align: left; }
thead th { background: #1b3a5c; color: white; font-weight: 600; }
tbody tr:nth-child(even) td { background: #f6f8fb; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
td.method { font-weight: 600; white-space: nowrap; }
td.best { background: #d9f2d9 !important; font-weight: bold; color: #14591c; }
td.failed { color: #a11; }
td.status.failed { background: #fdeaea !important; max-width: 30em; }
td.status.ok { color: #14591c; }
td.status.suspect { background: #fff4d6 !important; color: #8a5a00; max-width: 30em; }
td.partial { color: #8a5a00; }
td.suspect { color: #8a5a00; }
td.absent { color: #aaa; text-align: center; }
td.error { font-family: "DejaVu Sans Mono", monospace; font-size: 8pt; white-space: pre-wrap;
           word-break: break-word; max-width: 60em; }
td.pre { font-family: "DejaVu Sans Mono", monospace; font-size: 8pt; white-space: pre-wrap; }
td.key { font-weight: 600; white-space: nowrap; }
table.metadata td { max-width: 70em; word-break: break-word; }
figure { margin: 0.6em 0 1.2em; break-inside: avoid; page-break-inside: avoid; }
figure img { display: block; max-width: 100%; height: auto; border: 1px solid #e3e6ea; }
figcaption { font-size: 9pt; color: #444; margin-top: 0.3em; max-width: 60em; }
.legend { font-size: 9pt; color: #444; }
.legend .swatch { display: inline-block; padding: 0 0.4em; background: #d9f2d9; color: #14591c;
                  font-weight: bold; border: 1px solid #b5d9b5; }
div.figrow { display: flex; gap: 0.8em; align-items: flex-start; flex-wrap: wrap; }
div.figrow figure { flex: 1 1 0; min-width: 0; }
p.rule { font-size: 8.5pt; color: #444; margin-top: -0.8em; max-width: 75em; }
td.claim.met { background: #d9f2d9 !important; color: #14591c; font-weight: 600; }
td.claim.not-met { background: #fdeaea !important; color: #a11; font-weight: 600; }
td.claim.partly-met { background: #fff4d6 !important; color: #8a5a00; font-weight: 600; }
td.recommended { color: #14591c; font-weight: 600; }
table.verdict, table.claims { width: 100%; }
@media screen { .print-only { display: none; } }
@media print {
  body { padding: 0; max-width: none; font-size: 9.5pt; }
  section.surface figcaption { display: none; }
  table.verdict, table.claims, table.summary, table.overview, table.suspects, table.failures { font-size: 7.5pt; }
  th, td { padding: 0.12em 0.35em; }
  nav.toc { display: none; }
  section.surface h3 { margin: 0.2em 0 0; font-size: 10pt; }
  section.surface h2 { margin-top: 0; }
  section.surface figure { margin: 0.2em 0 0.4em; }
  div.figrow { display: block; }
  div.figrow figure { display: inline-block; vertical-align: top; margin: 0 0.4em 0.4em 0; }
  section.new-page { break-before: page; page-break-before: always; }
  thead { display: table-header-group; }
  tr { break-inside: avoid; page-break-inside: avoid; }
  div.table:not(.for-failures):not(.for-verdict):not(.for-claims) { break-inside: avoid; page-break-inside: avoid; }
  p.caption { break-after: avoid; page-break-after: avoid; }
  h2, h3, h2 + p, h3 + p { break-after: avoid; page-break-after: avoid; }
  nav.toc ol { columns: 3; }
}
"""


def anchor(title: str) -> str:
    """An id attribute value made from a title (lower-case letters, digits, dashes)."""
    return re.sub(r"[^a-z0-9]+", "-", title.lower()).strip("-") or "section"


def render_table(table: Table) -> str:
    """HTML of a :class:`parambench.reports.tables.Table` (texts escaped).

    Interactive tables get a search box (screen only) and ``data-sortable``; rows with
    keys get ``data-*`` attributes, which the detail view reads.
    """
    # The caption is a paragraph above the table rather than a <caption>, which would wrap
    # to the width of a narrow table; the wrapper keeps the two on one page.
    out = [f'<div class="table for-{html.escape(table.css_class or "plain")}">']
    if table.caption:
        out.append(f'<p class="caption">{html.escape(table.caption)}</p>')
    if table.interactive:
        out.append('<input type="search" class="table-filter screen-only" placeholder="filter rows…" '
                   'aria-label="filter the rows of the table below">')
    sortable = ' data-sortable="1"' if table.interactive else ""
    out.append(f'<table class="{html.escape(table.css_class)}"{sortable}>')
    out.append("<thead><tr>" + "".join(f"<th>{html.escape(c)}</th>" for c in table.columns) + "</tr></thead>")
    out.append("<tbody>")
    for r, row in enumerate(table.rows):
        cells = []
        for i, cell in enumerate(row):
            classes = list(cell.classes) + (["num"] if i in table.numeric else [])
            attrs = f' class="{" ".join(classes)}"' if classes else ""
            if cell.title:
                attrs += f' title="{html.escape(cell.title)}"'
            cells.append(f"<td{attrs}>{html.escape(cell.text)}</td>")
        keys = table.row_keys[r] if r < len(table.row_keys) else {}
        attrs = "".join(f' data-{html.escape(k)}="{html.escape(str(v))}"' for k, v in keys.items())
        out.append(f"<tr{attrs}>" + "".join(cells) + "</tr>")
    out.append("</tbody></table>")
    if table.note:
        out.append(f'<p class="rule">{html.escape(table.note)}</p>')
    out.append("</div>")
    return "\n".join(out)


#: Print size limits of a picture in CSS px (96 per inch): the page's text block is about
#: 1030 x 695 px (A4 landscape); each row of panels gets about a third of the page height,
#: so a heading, two one-row figures and their captions share a page.
_PRINT_MAX_WIDTH = 1000
_PRINT_ROW_HEIGHT = 215
_PRINT_MAX_HEIGHT = 620
_SCREEN_SCALE = 0.9  # the PNGs' pixels at 96 css px per inch look a bit large on screen


def print_size(picture: Picture, max_width: int = _PRINT_MAX_WIDTH, row_height: int | None = None) -> tuple[int, int]:
    """Width and height in CSS px at which a picture is printed.

    Explicit sizes rather than ``max-height``: WeasyPrint decides page breaks around an
    image from its unconstrained size, which left half-empty pages.

    Parameters
    ----------
    picture : Picture
    max_width : int
        Width limit in CSS px.
    row_height : int, optional
        Height limit per row of panels (default about a third of the page; the picture's own
        ``print_row_px`` when it has one).
    """
    w, h = picture.width_px * _SCREEN_SCALE, picture.height_px * _SCREEN_SCALE
    row = row_height or getattr(picture, "print_row_px", None) or _PRINT_ROW_HEIGHT
    limit = min(_PRINT_MAX_HEIGHT, row * max(1, picture.rows))
    scale = min(1.0, max_width / max(w, 1.0), limit / max(h, 1.0))
    return max(1, round(w * scale)), max(1, round(h * scale))


def render_picture(picture: Picture, ident: str = "") -> str:
    """HTML ``<figure>`` of a :class:`parambench.reports.figures.Picture` with its caption.

    ``ident`` becomes the image's id (the print style sheet sizes images by id). Pictures
    with located panels carry them as ``data-panels`` (JSON) and their surface as
    ``data-config``, for the detail view.
    """
    width = max(1, round(picture.width_px * _SCREEN_SCALE))
    id_attr = f' id="{ident}"' if ident else ""
    data = ""
    if picture.panels:
        data = f' data-panels="{html.escape(json.dumps(picture.panels, separators=(",", ":")))}"'
        config = getattr(picture, "config", "")
        if config:
            data += f' data-config="{html.escape(config)}"'
    return (f'<figure><img{id_attr} src="{picture.data_uri}" alt="{html.escape(picture.title)}" '
            f'width="{width}" style="width: {width}px; max-width: 100%;"{data}>'
            f"<figcaption>{html.escape(picture.caption)}</figcaption></figure>")


class _Renderer:
    """Renders sections, handing out unique ids and collecting per-image print sizes."""

    def __init__(self) -> None:
        self.used: set[str] = set()
        self.print_rules: list[str] = []

    def unique_id(self, title: str, prefix: str = "") -> str:
        base = f"{prefix}-{anchor(title)}" if prefix else anchor(title)
        candidate, n = base, 2
        while candidate in self.used:
            candidate, n = f"{base}-{n}", n + 1
        self.used.add(candidate)
        return candidate

    def block(self, block, level: int, prefix: str) -> str:
        if isinstance(block, Table):
            return render_table(block)
        if isinstance(block, Picture):
            return self.picture(block)
        if isinstance(block, Row):
            width = (_PRINT_MAX_WIDTH - 12 * len(block.pictures)) // max(1, len(block.pictures))
            return ('<div class="figrow">' + "".join(self.picture(p, width, block.row_height) for p in block.pictures)
                    + "</div>")
        if isinstance(block, Note):
            cls = f' class="{html.escape(block.kind)}"' if block.kind else ""
            return f"<p{cls}>{html.escape(block.text)}</p>"
        if isinstance(block, Section):
            return self.section(block, level, self.unique_id(block.title, prefix))
        if isinstance(block, str):  # trusted markup built in this package
            return block
        raise TypeError(f"cannot render a {type(block).__name__} block")

    def picture(self, picture: Picture, max_width: int = _PRINT_MAX_WIDTH, row_height: int | None = None) -> str:
        ident = f"fig-{len(self.print_rules) + 1}"
        w, h = print_size(picture, max_width, row_height)
        self.print_rules.append(f"img#{ident} {{ width: {w}px !important; height: {h}px !important; }}")
        return render_picture(picture, ident)

    def section(self, section: Section, level: int, ident: str) -> str:
        tag = f"h{min(level, 6)}"
        cls = ("major" if level == 2 else "minor") + (" new-page" if section.new_page else "")
        cls += f" {section.css_class}" if section.css_class else ""
        parts = [f'<section class="{cls}" id="{ident}">', f"<{tag}>{html.escape(section.title)}</{tag}>"]
        if section.intro:
            parts.append(f"<p>{html.escape(section.intro)}</p>")
        parts += [self.block(b, level + 1, ident) for b in section.blocks]
        parts.append("</section>")
        return "\n".join(parts)


def render_report(title: str, subtitle: str, sections: list[Section]) -> str:
    """The whole page.

    Parameters
    ----------
    title : str
    subtitle : str
        One line under the title (what was run, when).
    sections : list of Section
        Top-level sections, each listed in the table of contents.

    Returns
    -------
    str
        A complete HTML5 document.
    """
    renderer = _Renderer()
    ids = [renderer.unique_id(s.title) for s in sections]
    body = "\n".join(renderer.section(s, 2, i) for s, i in zip(sections, ids))
    print_style = "@media print {\n" + "\n".join(renderer.print_rules) + "\n}"
    toc = "".join(f'<li><a href="#{i}">{html.escape(s.title)}</a></li>' for i, s in zip(ids, sections))
    return f"""<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>{html.escape(title)}</title>
<link rel="icon" href="data:,">
<style>{_STYLE}
{INTERACTIVE_STYLE}
{print_style}</style>
</head>
<body>
<header>
<h1>{html.escape(title)}</h1>
<p class="subtitle">{html.escape(subtitle)}</p>
</header>
<nav class="toc"><strong>Contents</strong><ol>{toc}</ol></nav>
{body}
<div id="detail" class="screen-only" hidden role="dialog" aria-label="cell detail"></div>
<script>{SCRIPT}</script>
</body>
</html>
"""
