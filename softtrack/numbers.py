"""Numbers in settings: the finite-number check every settings class makes, and the range of
each numeric setting, declared once on its dataclass field (:func:`setting`) and read from
there by the class's own ``validate()`` (:func:`out_of_range`) and by the spec's Pydantic
models (:func:`range_of`), so that a range is written in one place."""

from __future__ import annotations

import dataclasses
import math
import numbers
from dataclasses import dataclass
from typing import Any

__all__ = ["Range", "is_finite_number", "out_of_range", "range_of", "setting"]

RANGE_KEY = "range"  # the dataclass field metadata key that holds a setting's Range


def is_finite_number(value: object) -> bool:
    """True for a real number (NumPy's included) that is finite; False for a bool, NaN, inf
    or anything else."""
    return (
        isinstance(value, numbers.Real)
        and not isinstance(value, bool)
        and math.isfinite(float(value))
    )


def _is_whole_number(value: object) -> bool:
    return isinstance(value, numbers.Integral) and not isinstance(value, bool)


@dataclass(frozen=True)
class Range:
    """The unit and the allowed values of one numeric setting.

    Attributes:
        unit: the unit as docs and ``--help`` print it (``-`` when dimensionless).
        gt, ge, lt, le: exclusive/inclusive lower and upper bounds (None: unbounded).
        whole: a whole number (else any finite real number).
        off: None is allowed too and switches the setting off.
        number: False for a setting that is not one number (a name, a vector, a switch): only
            its unit is declared here; its class checks it.
    """

    unit: str = "-"
    gt: float | None = None
    ge: float | None = None
    lt: float | None = None
    le: float | None = None
    whole: bool = False
    off: bool = False
    number: bool = True

    def admits(self, value: object) -> bool:
        """Whether ``value`` is a number of the right kind within the bounds."""
        if not self.number:
            return True
        if value is None:
            return self.off
        if not (_is_whole_number(value) if self.whole else is_finite_number(value)):
            return False
        number = float(value)  # type: ignore[arg-type]
        return (
            (self.gt is None or number > self.gt)
            and (self.ge is None or number >= self.ge)
            and (self.lt is None or number < self.lt)
            and (self.le is None or number <= self.le)
        )

    def describe(self) -> str:
        """What an admitted value is, e.g. ``a finite number > 0 m`` or ``a whole number ≥ 1``."""
        kind = "a whole number" if self.whole else "a finite number"
        low = f"({self.gt:g}" if self.gt is not None else None
        low = f"[{self.ge:g}" if self.ge is not None else low
        high = f"{self.lt:g})" if self.lt is not None else None
        high = f"{self.le:g}]" if self.le is not None else high
        if low and high:
            bounds = f" in {low}, {high}"
        elif low:
            bounds = f" {'>' if low[0] == '(' else '≥'} {low[1:]}"
        elif high:
            bounds = f" {'<' if high[-1] == ')' else '≤'} {high[:-1]}"
        else:
            bounds = ""
        unit = f" {self.unit}" if self.unit not in ("", "-") else ""
        return f"{kind}{bounds}{unit}" + (" (or None = off)" if self.off else "")

    def constraints(self) -> dict[str, float]:
        """The bounds as Pydantic ``Field`` keywords (``gt``, ``ge``, ``lt``, ``le``)."""
        bounds = {"gt": self.gt, "ge": self.ge, "lt": self.lt, "le": self.le}
        return {name: bound for name, bound in bounds.items() if bound is not None}


def setting(default: Any, unit: str = "-", **bounds: Any) -> Any:
    """A dataclass field with ``default`` and its :class:`Range` (``unit``, ``gt``, ``ge``,
    ``lt``, ``le``, ``whole``, ``off``, ``number``) in its metadata."""
    return dataclasses.field(default=default, metadata={RANGE_KEY: Range(unit, **bounds)})


def range_of(settings: type, name: str) -> Range:
    """The :class:`Range` declared on field ``name`` of the dataclass ``settings``.

    Raises:
        KeyError: when the field does not exist or declares no range.
    """
    for field in dataclasses.fields(settings):
        if field.name == name and RANGE_KEY in field.metadata:
            range_: Range = field.metadata[RANGE_KEY]
            return range_
    raise KeyError(f"{settings.__name__}.{name} declares no range")


def out_of_range(settings: object, prefix: str = "") -> str | None:
    """``"<prefix><name>=<value> must be <range>"`` for the first field of the dataclass
    instance ``settings`` outside its declared :class:`Range`; None when all are within."""
    for field in dataclasses.fields(settings):  # type: ignore[arg-type]
        range_ = field.metadata.get(RANGE_KEY)
        value = getattr(settings, field.name)
        if range_ is not None and not range_.admits(value):
            return f"{prefix}{field.name}={value!r} must be {range_.describe()}"
    return None
