"""Building blocks of the spec models: :class:`SpecError`, the validation-error helper, the
reusable field types (numbers that reject booleans, fixed-length vectors, seeds), the field
constructors that put each unit into the description, and the :class:`SpecModel` base class.
See :mod:`softtrack.spec`."""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from pathlib import Path
from typing import Annotated, Any

from pydantic import BaseModel, BeforeValidator, ConfigDict, Field, field_validator
from pydantic_core import PydanticCustomError

from softtrack.numbers import range_of

ERROR_TYPE = "softtrack"  # type of the PydanticCustomErrors raised by our own validators


# ------------------------------------------------------------------------------------------
# The error type
# ------------------------------------------------------------------------------------------
class SpecError(Exception):
    """A user error in a spec file or a ``--set`` override.

    ``str(error)`` is one line: ``<file>[:<line>]: <field.path>: <problem>; <fix>`` (the field
    path is left out for errors about the file as a whole).

    Attributes:
        file: the spec file (or ``--set path=value`` for an override), as given.
        field: dotted field path such as ``env.physics.dt``; ``""`` for file-level errors.
        problem: what is wrong.
        fix: how to fix it (may be ``""``).
        line: 1-based line in ``file``, when known.
    """

    def __init__(
        self,
        file: str | Path,
        problem: str,
        fix: str = "",
        *,
        field: str = "",
        line: int | None = None,
    ) -> None:
        self.file = str(file)
        self.field = field
        self.problem = _one_line(problem)
        self.fix = _one_line(fix)
        self.line = line
        super().__init__(str(self))

    def __str__(self) -> str:
        where = f"{self.file}:{self.line}" if self.line else self.file
        head = f"{where}: {self.field}: " if self.field else f"{where}: "
        return head + self.problem + (f"; {self.fix}" if self.fix else "")


def _one_line(text: str) -> str:
    return " ".join(str(text).split())


def custom_error(message: str, field: str | tuple[str, ...] = "") -> PydanticCustomError:
    """A validation error with our own ``problem; fix`` text; ``field`` (dotted, or its parts
    when a part holds a dot) is appended to its path."""
    return PydanticCustomError(ERROR_TYPE, "{message}", {"message": message, "field": field})


#: Range of a whole number in a spec: what a signed 64-bit store column holds.
INT64_MIN, INT64_MAX = -(2**63), 2**63 - 1


def check_int64(value: Any) -> None:
    """Raise a validation error if ``value`` (or a whole number inside a list or mapping) does
    not fit a signed 64-bit integer."""
    if isinstance(value, int) and not isinstance(value, bool):
        if not INT64_MIN <= value <= INT64_MAX:
            raise custom_error(
                f"{value} does not fit a 64-bit integer (at most {INT64_MAX:,}); "
                "use a smaller number"
            )
    elif isinstance(value, (list, tuple)):
        for item in value:
            check_int64(item)
    elif isinstance(value, dict):
        for item in value.values():
            check_int64(item)


# ------------------------------------------------------------------------------------------
# Reusable field types
# ------------------------------------------------------------------------------------------
def _reject_bool(value: Any) -> Any:
    if isinstance(value, bool):
        raise custom_error(f"expected a number, got {str(value).lower()}; write a number instead")
    return value


def _fixed_length(n: int, example: str) -> BeforeValidator:
    def check(value: Any) -> Any:
        if isinstance(value, (list, tuple)) and len(value) != n:
            raise custom_error(f"expected {n} values, got {len(value)}; write it as {example}")
        return value

    return BeforeValidator(check)


Int = Annotated[int, BeforeValidator(_reject_bool)]
Float = Annotated[float, BeforeValidator(_reject_bool)]
Vec3 = Annotated[tuple[Float, Float, Float], _fixed_length(3, "[x, y, z]")]
Pair = Annotated[tuple[Float, Float], _fixed_length(2, "[first, second]")]
Seed = Annotated[int, BeforeValidator(_reject_bool), Field(ge=0, lt=2**32)]


def _factor(value: Any) -> Any:
    """A positive factor, or a [low, high] range of them (``[f, f]`` becomes ``f``)."""
    example = "write a factor such as 1.2 or a range [low, high] such as [0.8, 1.2]"

    def number(v: Any) -> float:
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            shown = str(v).lower() if isinstance(v, bool) else repr(v)
            raise custom_error(f"expected a number, got {shown}; {example}")
        if not (math.isfinite(v) and v > 0):
            raise custom_error(f"a factor must be a finite number > 0, got {v!r}; {example}")
        return float(v)

    if isinstance(value, (list, tuple)):
        if len(value) != 2:
            raise custom_error(f"a range has 2 values [low, high], got {len(value)}; {example}")
        low, high = number(value[0]), number(value[1])
        if low > high:
            raise custom_error(
                f"range [{low:g}, {high:g}] has low > high; write it as [{high:g}, {low:g}]"
            )
        return low if low == high else (low, high)
    return number(value)


# A fixed factor (float) or a [low, high] range drawn per episode (tuple); > 0 each.
Factor = Annotated[float | tuple[float, float], BeforeValidator(_factor)]


# ------------------------------------------------------------------------------------------
# Field constructors and the base model
# ------------------------------------------------------------------------------------------
def unit_field(default: Any, text: str, unit: str, **constraints: Any) -> Any:
    """A field whose description ends with its unit in brackets."""
    return Field(default, description=f"{text} [{unit}]", **constraints)


def check_with_dataclass(model: BaseModel, validate: Callable[[], object]) -> None:
    """Run the ``validate`` of the dataclass that spec section ``model`` configures; its
    ``ValueError`` ("[section ]<field>=<value> must be …") becomes a validation error on that
    field, so the cross-field checks are the dataclass's, written once."""
    try:
        validate()
    except ValueError as exc:
        message = str(exc)
        match = re.match(r"^(?:\w+ )?(\w+)=", message)
        named = match.group(1) if match else ""
        raise custom_error(message, named if named in type(model).model_fields else "") from None


def setting_field(settings: type, name: str, text: str, **shape: Any) -> Any:
    """A field that configures field ``name`` of the dataclass ``settings``: its default, unit
    and range are that field's (:func:`softtrack.numbers.setting`), written once there; ``text``
    describes it; ``shape`` adds Pydantic's length keywords for a list (``min_length``)."""
    range_ = range_of(settings, name)
    default = settings.__dataclass_fields__[name].default  # type: ignore[attr-defined]
    keywords: dict[str, Any] = {**range_.constraints(), **shape}
    return Field(default, description=f"{text} [{range_.unit}]", **keywords)


def section_field(cls: type[BaseModel], text: str) -> Any:
    """A field holding a whole sub-section, defaulting to that section's defaults."""
    return Field(default_factory=cls, description=text)


class SpecModel(BaseModel):
    """Base of every spec model: unknown keys and NaN/inf are rejected; defaults are trusted
    (not re-validated)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False, validate_default=False)

    @field_validator("*", mode="after")
    @classmethod
    def _fits_the_store(cls, value: Any) -> Any:
        """Every whole number fits a signed 64-bit integer, as run.json and the tables hold
        them (``total_timesteps`` of 2**63 would train, then break every query)."""
        check_int64(value)
        return value
