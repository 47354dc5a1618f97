"""A generated section of a Markdown page: the text between two marker comments, replaced
by the script that computes it (the README's and the docs' generated tables)."""

from __future__ import annotations

from pathlib import Path


def write_between(path: Path, start: str, end: str, body: str) -> None:
    """Replace the text between the markers ``start`` and ``end`` of ``path`` with ``body``
    (the markers stay, each on a line of its own).

    Raises:
        ValueError: ``path`` lacks one of the markers (nothing is written).
    """
    text = Path(path).read_text()
    if start not in text or end not in text:
        raise ValueError(f"{path} has no {start} ... {end} markers")
    head, rest = text.split(start, 1)
    _, tail = rest.split(end, 1)
    Path(path).write_text(f"{head}{start}\n{body}\n{end}{tail}")
