"""The one rule for a count a caller gives (``kinegrasp_env.counts.check_count``): what it
takes and what it refuses, by construction."""

from __future__ import annotations

import numpy as np
import pytest

from kinegrasp_env.counts import check_count


@pytest.mark.parametrize("value, least, expected", [(3, 1, 3), (np.int64(2), 1, 2),
                                                    (np.uint8(1), 1, 1), (0, 0, 0)])
def test_integers_at_or_above_the_least_are_taken(value, least, expected):
    out = check_count(value, "n", least)
    assert out == expected and type(out) is int


@pytest.mark.parametrize("value", [0, -1, True, False, 2.0, 2.5, "3", None, np.float64(4)])
def test_anything_else_is_one_line_naming_the_value(value):
    with pytest.raises(ValueError) as info:
        check_count(value, "samples")
    assert str(info.value) == f"samples must be an integer >= 1, got {value!r}"
