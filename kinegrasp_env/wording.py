"""Words for counts, and numbers as they are printed, in what the package prints and draws."""

from __future__ import annotations


def plural(count: int, word: str, many: str | None = None) -> str:
    """``1 angle``, ``2 angles`` (``many``: the plural when not ``word + "s"``)."""
    return f"{count} {word if count == 1 else (many or word + 's')}"


def fixed(value: float, digits: int, sign: str = "") -> str:
    """``value`` to ``digits`` decimals, rounded first so that a tiny negative value prints
    as 0, not -0.000 (``sign="+"``: a sign on every value, ``+0.000`` for it)."""
    return f"{round(float(value), digits) + 0.0:{sign}.{digits}f}"
