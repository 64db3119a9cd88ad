"""The one check every settings class makes of a numeric field: a finite real number."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["is_finite_number"]


def is_finite_number(value: object) -> bool:
    """True for an int or float (NumPy's included) that is finite; False for a bool, NaN, inf
    or anything else."""
    return (
        isinstance(value, (int, float, np.integer, np.floating))
        and not isinstance(value, bool)
        and math.isfinite(float(value))
    )
