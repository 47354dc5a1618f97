"""Words for counts in what the package prints and draws."""

from __future__ import annotations


def plural(count: int, word: str, many: str | None = None) -> str:
    """``1 angle``, ``2 angles`` (``many``: the plural when not ``word + "s"``)."""
    return f"{count} {word if count == 1 else (many or word + 's')}"
