"""What every section of the report uses: numbers as the tables show them, figures with captions."""

from __future__ import annotations

import html


def fmt(v: float | None, spec: str = ".4g") -> str:
    """``v`` formatted with ``spec`` (``".1%"``: a percentage); a dash when there is none."""
    return "&ndash;" if v is None else format(v, spec)


def figure(image: str | None, caption: str) -> str:
    """A ``<figure>`` of an ``<img>`` tag and its caption (nothing without an image: a run made
    without figures)."""
    if not image:
        return ""
    return f"<figure>{image}<figcaption>{html.escape(caption)}</figcaption></figure>"


__all__ = ["fmt", "figure"]
