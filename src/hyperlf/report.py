"""A single self-contained HTML report (pictures embedded as base64 PNG) for ``hyperlf demo``.

Kept deliberately small: a title, then sections, each with text, a table of figures and
pictures. The file is written atomically.
"""

from __future__ import annotations

import base64
import html
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Sequence

from ._atomic import atomic_write_text
from ._options import path_like, shown, text
from .errors import DataNotFoundError, InvalidInputError

__all__ = ["Section", "write_html_report"]


@dataclass
class Section:
    """One section of the report.

    Attributes
    ----------
    title : str
        Section heading.
    text : str
        One paragraph (escaped).
    table : sequence of sequence of str
        Rows of a table; the first row is the header.
    pictures : sequence of (path, caption)
        PNG or GIF files embedded in the report.
    """

    title: str
    text: str = ""
    table: Sequence[Sequence[str]] = ()  # first row = header
    pictures: Sequence[tuple[str | os.PathLike, str]] = field(default_factory=list)  # (path, caption)

    def __post_init__(self) -> None:
        _text(self.title, "title"), _text(self.text, "text")
        if not _rows(self.table):
            raise InvalidInputError(f"table must be a list of rows (each a list of cells), got "
                                    f"{shown(self.table)}")
        if not _rows(self.pictures) or any(len(p) != 2 for p in self.pictures):
            raise InvalidInputError(f"pictures must be a list of (path, caption) pairs, got "
                                    f"{shown(self.pictures)}")
        for pic, caption in self.pictures:
            path_like(pic, "picture", folder=None), _text(caption, "caption")


def _text(value, label: str) -> str:
    return text(value, label)


def _rows(value) -> bool:
    """Whether ``value`` is a list or tuple of lists or tuples (a table's rows)."""
    return isinstance(value, (list, tuple)) and all(isinstance(r, (list, tuple)) for r in value)


_STYLE = """
body { font-family: system-ui, sans-serif; margin: 2em auto; max-width: 1100px; color: #222; }
h1 { font-size: 1.6em; } h2 { font-size: 1.2em; margin-top: 2em; border-bottom: 1px solid #ccc; }
figure { display: inline-block; margin: 0.5em; vertical-align: top; text-align: center; }
figure img { max-width: 520px; max-height: 420px; image-rendering: pixelated; }
figcaption { font-size: 0.85em; color: #555; max-width: 520px; }
table { border-collapse: collapse; margin: 0.5em 0; } td, th { border: 1px solid #ccc;
padding: 0.25em 0.6em; text-align: right; } th { background: #f3f3f3; }
p.small { font-size: 0.85em; color: #666; }
"""


def _img_tag(path: Path) -> str:
    data = base64.b64encode(Path(path).read_bytes()).decode("ascii")
    mime = "image/gif" if Path(path).suffix.lower() == ".gif" else "image/png"
    return f'<img src="data:{mime};base64,{data}" alt="{html.escape(Path(path).name)}">'


def write_html_report(path: str | os.PathLike, title: str, sections: Sequence[Section],
                      footer: str = "") -> Path:
    """Write an HTML report with every picture embedded, so the one file can be shared.

    Parameters
    ----------
    path : path-like
        Output ``.html`` (written atomically).
    title : str
        Page title and heading.
    sections : sequence of Section
        The sections, in order.
    footer : str
        Small print at the end (e.g. timings).

    Returns
    -------
    Path
        ``path``: one self-contained page that needs none of the picture files.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "r.html"
    >>> rep = write_html_report(out, "demo", [Section("a", "text", [("x",), ("1",)])])
    >>> "<h2>a</h2>" in rep.read_text()
    True
    """
    path_like(path)
    _text(title, "title"), _text(footer, "footer")
    if not isinstance(sections, (list, tuple)) or not all(isinstance(sec, Section)
                                                          for sec in sections):
        raise InvalidInputError(f"sections must be a list of hyperlf.report.Section, got "
                                f"{shown(sections)}")
    missing = [os.fspath(pic) for sec in sections for pic, _ in sec.pictures
               if not Path(pic).is_file()]
    if missing:
        raise DataNotFoundError(f"picture {missing[0]} not found"
                                + (f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""))
    parts = [f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(title)}"
             f"</title><style>{_STYLE}</style></head><body><h1>{html.escape(title)}</h1>"]
    for sec in sections:
        parts.append(f"<h2>{html.escape(sec.title)}</h2>")
        if sec.text:
            parts.append(f"<p>{html.escape(sec.text)}</p>")
        if sec.table:
            head, *rows = sec.table
            parts.append("<table><tr>" + "".join(f"<th>{html.escape(str(h))}</th>" for h in head)
                         + "</tr>")
            for row in rows:
                parts.append("<tr>" + "".join(f"<td>{html.escape(str(v))}</td>" for v in row)
                             + "</tr>")
            parts.append("</table>")
        for pic, caption in sec.pictures:
            parts.append(f"<figure>{_img_tag(Path(pic))}<figcaption>{html.escape(caption)}"
                         "</figcaption></figure>")
    if footer:
        parts.append(f"<p class='small'>{html.escape(footer)}</p>")
    parts.append("</body></html>")
    return atomic_write_text(path, "\n".join(parts))
