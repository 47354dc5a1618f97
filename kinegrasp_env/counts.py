"""One rule for a count a caller gives (draws, processes, IK starts, grasps, contacts, steps)."""

from __future__ import annotations


def check_count(value, name: str, least: int = 1) -> int:
    """``value`` as an int, or ValueError (one line, naming ``name`` and the value) unless it
    is an integer >= ``least``: a Python or NumPy integer, not a bool (a flag passed by
    mistake) and not a float (2.0 included: a count is not a measurement)."""
    if isinstance(value, bool) or not hasattr(value, "__index__") or value < least:
        raise ValueError(f"{name} must be an integer >= {least}, got {value!r}")
    return int(value)
