"""Number formatting shared by the report's tables."""

from __future__ import annotations

import math

__all__ = ["mean_pm_std"]


def mean_pm_std(mean: float | None, std: float | None, digits: int, scale: float = 1.0) -> str:
    """``0.0652 ± 0.0031`` (both × ``scale``); just the mean when the std is undefined (one
    seed); "no data" when there is no finite mean."""
    if mean is None or not math.isfinite(mean):
        return "no data"
    if std is None or not math.isfinite(std):
        return f"{scale * mean:.{digits}f}"
    return f"{scale * mean:.{digits}f} ± {scale * std:.{digits}f}"
