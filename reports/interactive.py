"""The report page's small inline script and its styles: sortable, filterable tables and a detail view.

No library and no request: about a hundred lines of plain JavaScript, so the HTML stays one
self-contained file. What it does:

* a click on a header of a table marked ``data-sortable`` sorts its rows by that column
  (numbers by value, "—" last; a second click reverses), and sets ``aria-sort``;
* the search box above such a table hides the rows that do not contain its text;
* a click on a summary-table row (``data-config``, ``data-variant``) opens a panel with that
  method's crops of its surface's uv-layout and checkerboard figures: the crops reuse the
  figure already in the page (``data-panels`` gives each method's panel as fractions of the
  image), so the detail view adds no image data to the file. Escape or the close button
  closes it.
"""

from __future__ import annotations

__all__ = ["SCRIPT", "STYLE"]

STYLE = """
th[data-sort] { cursor: pointer; }
th[aria-sort="ascending"]::after { content: " \\25B2"; font-size: 7pt; }
th[aria-sort="descending"]::after { content: " \\25BC"; font-size: 7pt; }
input.table-filter { font-size: 9pt; margin: 0 0 0.3em; padding: 0.15em 0.4em; width: 16em; }
table.summary tbody tr[data-variant] { cursor: zoom-in; }
#detail { position: fixed; top: 3%; right: 2%; max-width: 46%; max-height: 92%; overflow: auto; background: white;
          border: 2px solid #1b3a5c; box-shadow: 0 4px 18px rgba(0,0,0,0.3); padding: 0.6em 0.9em; z-index: 10; }
#detail .crop { background-repeat: no-repeat; border: 1px solid #dde3ea; margin: 0.3em 0.4em 0.3em 0;
                display: inline-block; vertical-align: top; }
#detail button { float: right; }
@media print { .screen-only, #detail { display: none !important; } }
"""

SCRIPT = r"""
(function () {
  function cellValue(row, i) {
    var cell = row.cells[i];
    var text = cell ? cell.textContent.trim() : "";
    var number = parseFloat(text.replace(/[^0-9eE+.\-]+.*$/, ""));
    return {text: text, number: (text === "" || text === "\u2014" || isNaN(number)) ? null : number};
  }
  function compare(a, b) {
    if (a.number !== null && b.number !== null) return a.number - b.number;
    if (a.number !== null) return -1;
    if (b.number !== null) return 1;
    if (a.text === "\u2014") return 1;
    if (b.text === "\u2014") return -1;
    return a.text.localeCompare(b.text);
  }
  function sortBy(table, index, th) {
    var body = table.tBodies[0];
    var descending = th.getAttribute("aria-sort") === "ascending";
    var rows = Array.prototype.slice.call(body.rows);
    rows.sort(function (r, s) {
      var order = compare(cellValue(r, index), cellValue(s, index));
      return descending ? -order : order;
    });
    rows.forEach(function (r) { body.appendChild(r); });
    Array.prototype.forEach.call(table.tHead.rows[0].cells, function (h) { h.removeAttribute("aria-sort"); });
    th.setAttribute("aria-sort", descending ? "descending" : "ascending");
  }
  document.querySelectorAll("table[data-sortable]").forEach(function (table) {
    if (!table.tHead || !table.tBodies.length) return;
    Array.prototype.forEach.call(table.tHead.rows[0].cells, function (th, i) {
      th.setAttribute("data-sort", "1");
      th.title = "sort by this column";
      th.addEventListener("click", function () { sortBy(table, i, th); });
    });
    var box = table.previousElementSibling;
    if (box && box.classList.contains("table-filter")) {
      box.addEventListener("input", function () {
        var query = box.value.trim().toLowerCase();
        Array.prototype.forEach.call(table.tBodies[0].rows, function (r) {
          r.hidden = query !== "" && r.textContent.toLowerCase().indexOf(query) < 0;
        });
      });
    }
  });
  var detail = document.getElementById("detail");
  function crop(img, box, width) {
    var w = img.naturalWidth, h = img.naturalHeight;
    var scale = width / ((box[2] - box[0]) * w);
    var div = document.createElement("div");
    div.className = "crop";
    div.style.width = width + "px";
    div.style.height = Math.round((box[3] - box[1]) * h * scale) + "px";
    div.style.backgroundImage = "url(\"" + img.src + "\")";
    div.style.backgroundSize = Math.round(w * scale) + "px " + Math.round(h * scale) + "px";
    div.style.backgroundPosition = (-box[0] * w * scale) + "px " + (-box[1] * h * scale) + "px";
    div.title = img.alt;
    return div;
  }
  function show(row) {
    var config = row.getAttribute("data-config"), variant = row.getAttribute("data-variant");
    detail.innerHTML = "";
    var close = document.createElement("button");
    close.textContent = "close";
    close.addEventListener("click", function () { detail.hidden = true; });
    detail.appendChild(close);
    var title = document.createElement("h3");
    title.textContent = variant + " \u2014 " + config;
    detail.appendChild(title);
    var facts = document.createElement("p");
    var heads = row.closest("table").tHead.rows[0].cells;
    facts.textContent = Array.prototype.map.call(row.cells, function (c, i) {
      return heads[i].textContent + ": " + c.textContent; }).slice(1).join(" \u00b7 ");
    detail.appendChild(facts);
    var found = 0;
    document.querySelectorAll("img[data-panels]").forEach(function (img) {
      if (img.getAttribute("data-config") !== config) return;
      var box = JSON.parse(img.getAttribute("data-panels"))[variant];
      if (!box) return;
      // At most 1.6x the panel's own pixels: larger only blurs it.
      var native = (box[2] - box[0]) * img.naturalWidth;
      detail.appendChild(crop(img, box, Math.round(Math.min(320, Math.max(160, 1.6 * native)))));
      found += 1;
    });
    if (!found) {
      var none = document.createElement("p");
      none.className = "muted";
      none.textContent = "No picture of this cell in the report (failed, or not the surface drawn).";
      detail.appendChild(none);
    }
    detail.hidden = false;
  }
  document.querySelectorAll("tr[data-variant]").forEach(function (row) {
    row.addEventListener("click", function () { show(row); });
  });
  document.addEventListener("keydown", function (e) { if (e.key === "Escape") detail.hidden = true; });
})();
"""
