"""Print the report's HTML to PDF with WeasyPrint (same page, print style rules)."""

from __future__ import annotations

import logging
from pathlib import Path

from parambench.bench.storage import atomic_write_bytes

__all__ = ["write_pdf"]


def write_pdf(html_text: str, path: Path, base_url: Path | None = None) -> Path:
    """Render an HTML document to a PDF file.

    Parameters
    ----------
    html_text : str
        A complete, self-contained HTML document (images as data URIs).
    path : pathlib.Path
        The PDF to write; its folder must exist.
    base_url : pathlib.Path, optional
        Folder relative links would resolve against (the report has none; given for safety).

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    from weasyprint import HTML  # imported here: it is slow to import and only the PDF needs it

    # WeasyPrint logs every CSS property it does not support at WARNING; the report's style
    # sheet targets browsers too, so those messages are noise here.
    logger = logging.getLogger("weasyprint")
    level = logger.level
    logger.setLevel(logging.ERROR)
    try:
        pdf = HTML(string=html_text, base_url=str(base_url or path.parent)).write_pdf()
    finally:
        logger.setLevel(level)
    atomic_write_bytes(path, pdf)  # never a half-written PDF, nor one shared with a second writer
    return path
