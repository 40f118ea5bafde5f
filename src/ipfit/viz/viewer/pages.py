"""HTML pages: the standalone page around a figure, and an index page of several."""

from __future__ import annotations

import html
import os
from pathlib import Path

from numpy.typing import ArrayLike

from ..._utils.validation import error
from .figure import result_figure

__all__ = ["page", "to_html", "write_html", "index_page", "write_plotly_script", "PLOTLY_SCRIPT"]

#: The file name of plotly's script when pages share one copy beside them
#: (``write_html(..., include_plotlyjs=PLOTLY_SCRIPT)`` and :func:`write_plotly_script`).
PLOTLY_SCRIPT = "plotly.min.js"


def page(title: str, body: str) -> str:
    """A minimal standalone HTML page around ``body`` (the viewer's and the index page's)."""
    return ("<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">"
            f"<title>{html.escape(title)}</title>"
            "<style>html,body{margin:0;height:100%;font-family:sans-serif}</style></head>\n"
            f"<body>{body}</body></html>\n")


def to_html(result, points: ArrayLike | None = None, *, full_html: bool = True, include_plotlyjs=True,
            **kwargs) -> str:
    """The viewer as HTML: a whole offline page, or with ``full_html=False`` a ``<div>`` (notebooks).

    ``include_plotlyjs=True`` inlines plotly's JavaScript (offline, ~4.8 MB); other values
    are passed to plotly (e.g. ``"cdn"``, or :data:`PLOTLY_SCRIPT`: a script beside the page,
    written once for many pages by :func:`write_plotly_script`). ``kwargs`` go to
    :func:`result_figure`.
    """
    fig = result_figure(result, points, **kwargs)
    div = fig.to_html(full_html=False, include_plotlyjs=include_plotlyjs, default_width="100%",
                      default_height="100vh" if full_html else "720px", config={"responsive": True})
    if not full_html:
        return div
    return page(f"ipfit viewer: {fig.layout.title.text}", div)


def write_html(result, points: ArrayLike | None, path: str | os.PathLike, **kwargs) -> None:
    """Write the viewer page of ``result`` to ``path`` atomically (see :func:`result_figure`)."""
    from ..._utils.atomic import write_text_atomic

    # Checked before the figure is built: a big result takes seconds to draw.
    if not str(path).lower().endswith((".html", ".htm")):
        raise error("path", "a file name ending in .html", repr(str(path)), "Name the page e.g. view.html.")
    folder = Path(path).parent
    if not folder.is_dir():
        raise error("path", "a file in an existing folder", f"{str(path)!r}", f"Create {folder} first.")
    write_text_atomic(path, to_html(result, points, **kwargs))


def write_plotly_script(folder: str | os.PathLike) -> Path:
    """Write plotly's JavaScript to ``folder/plotly.min.js`` (atomically) and return its path.

    Pages written with ``include_plotlyjs=PLOTLY_SCRIPT`` into the same folder load it: a batch's
    pages then share one copy (~4.8 MB) instead of each inlining its own, and still work offline.
    """
    from ..._utils.atomic import write_text_atomic
    from .figure import _plotly

    _plotly()  # plotly missing: the viewer's one-line error
    from plotly.offline import get_plotlyjs

    path = Path(folder) / PLOTLY_SCRIPT
    write_text_atomic(path, get_plotlyjs())
    return path


def index_page(title: str, entries) -> str:
    """An index of viewers: one card per ``(name, page, thumbnail, caption)``, each thumbnail (a
    relative image path, or None) linking to its viewer page (relative path).

    >>> html_text = index_page("shapes", [("boot", "boot.html", "boot.png", "degree 4")])
    >>> '<a href="boot.html"><img src="boot.png"' in html_text
    True
    """
    cards = []
    for name, target, thumbnail, caption in entries:
        image = (f'<img src="{html.escape(thumbnail)}" alt="{html.escape(name)}" loading="lazy">'
                 if thumbnail else "")
        cards.append(f'<figure><a href="{html.escape(target)}">{image}</a><figcaption><a href="{html.escape(target)}">'
                     f"{html.escape(name)}</a><br>{html.escape(caption)}</figcaption></figure>")
    style = ("<style>main{display:flex;flex-wrap:wrap;gap:12px;padding:12px}figure{margin:0;width:260px}"
             "img{width:260px;border:1px solid #ccc}figcaption{font-size:13px}</style>")
    return page(title, f"{style}<h2 style='padding:0 12px'>{html.escape(title)}</h2><main>{''.join(cards)}</main>")
