"""Reading specs: the YAML loader with line numbers, ``--set`` overrides, and the
conversion of Pydantic errors into one-line :class:`SpecError` messages."""

from __future__ import annotations

import difflib
import re
import types
import typing
from collections.abc import Iterable, Sequence
from typing import Any

import yaml
from pydantic import (
    BaseModel,
    ValidationError,
)
from pydantic_core import ErrorDetails

from softtrack.spec.fields import ERROR_TYPE, SpecError


# ------------------------------------------------------------------------------------------
# YAML reading
# ------------------------------------------------------------------------------------------
class _Loader(yaml.SafeLoader):
    """``yaml.SafeLoader`` that reads ``1e7``/``3e-4`` as floats (YAML 1.2) and rejects
    duplicate keys. It constructs only plain data (no Python objects)."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        if isinstance(node, yaml.MappingNode):
            seen: dict[Any, int] = {}
            for key_node, _ in node.value:
                if key_node.tag == "tag:yaml.org,2002:merge":
                    continue
                key = self.construct_object(key_node, deep=deep)
                try:
                    if key in seen:
                        raise yaml.constructor.ConstructorError(
                            None,
                            None,
                            f"duplicate key {key!r} (first given on line {seen[key] + 1})",
                            key_node.start_mark,
                        )
                    seen[key] = key_node.start_mark.line
                except TypeError:  # unhashable key: let SafeLoader report it
                    pass
        return super().construct_mapping(node, deep=deep)


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*)(?:\.[0-9_]*)?[eE][-+]?[0-9]+$"),
    list("-+0123456789"),
)


#: Largest number of values a spec may expand to with its aliases (``*name``) resolved; a
#: spec holds a few hundred, a "billion laughs" alias bomb billions.
MAX_YAML_VALUES = 100_000
#: Deepest nesting of lists and mappings a spec may have (a spec nests about 5 deep).
MAX_YAML_DEPTH = 64


def _check_yaml_size(text: str, label: str) -> None:
    """Reject, before building anything, YAML nested deeper than :data:`MAX_YAML_DEPTH` or
    expanding (aliases resolved) to more than :data:`MAX_YAML_VALUES` values.

    Walks the parser's events, which needs neither recursion nor the expanded data.
    """
    open_sizes: list[int] = []  # values inside each open collection so far
    open_anchors: list[str | None] = []
    anchored: dict[str, int] = {}  # anchor -> number of values it expands to
    total = 0

    def close(size: int, anchor: str | None) -> None:
        nonlocal total
        if anchor is not None:
            anchored[anchor] = size
        if open_sizes:
            open_sizes[-1] += size
        else:
            total += size
        if max(total, open_sizes[-1] if open_sizes else 0) > MAX_YAML_VALUES:
            raise SpecError(
                label,
                f"the YAML expands to more than {MAX_YAML_VALUES:,} values (aliases resolved)",
                "a spec holds a few hundred values; remove the repeated aliases (*name)",
            )

    try:
        for event in yaml.parse(text, Loader=_Loader):
            if isinstance(event, yaml.CollectionStartEvent):
                if len(open_sizes) >= MAX_YAML_DEPTH:
                    raise SpecError(
                        label,
                        f"the YAML nests lists/mappings more than {MAX_YAML_DEPTH} deep",
                        "a spec nests about 5 deep; fix the brackets",
                        line=event.start_mark.line + 1 if event.start_mark else None,
                    )
                open_sizes.append(1)
                open_anchors.append(event.anchor)
            elif isinstance(event, yaml.CollectionEndEvent):
                close(open_sizes.pop(), open_anchors.pop())
            elif isinstance(event, yaml.ScalarEvent):
                close(1, event.anchor)
            elif isinstance(event, yaml.AliasEvent):
                if event.anchor not in anchored:  # unknown or recursive: the composer says which
                    return
                close(anchored[event.anchor], None)
    except yaml.YAMLError:
        return  # malformed: _parse_yaml reports it with its line


def _parse_yaml(text: str, label: str) -> tuple[Any, dict[tuple[Any, ...], int]]:
    """Parse one YAML document; returns the data and a map field-path → 1-based line.

    Raises:
        SpecError: malformed YAML, or YAML too deep or too large (:func:`_check_yaml_size`).
    """
    _check_yaml_size(text, label)
    loader = _Loader(text)
    try:
        node = loader.get_single_node()
        data = loader.construct_document(node) if node is not None else None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        line = mark.line + 1 if mark is not None else None
        column = f", column {mark.column + 1}" if mark is not None else ""
        problem = exc.problem or exc.context or "invalid YAML"
        raise SpecError(
            label,
            f"malformed YAML{column}: {problem}",
            "fix the YAML syntax at that line",
            line=line,
        ) from None
    except (yaml.YAMLError, RecursionError) as exc:
        raise SpecError(label, f"malformed YAML: {exc}", "fix the YAML syntax") from None
    finally:
        loader.dispose()
    lines: dict[tuple[Any, ...], int] = {}
    if node is not None:
        _collect_lines(node, (), lines)
    return data, lines


def _collect_lines(node: yaml.Node, path: tuple[Any, ...], out: dict[tuple[Any, ...], int]) -> None:
    out.setdefault(path, node.start_mark.line + 1)
    if isinstance(node, yaml.MappingNode):
        for key_node, value_node in node.value:
            if isinstance(key_node, yaml.ScalarNode):
                out[(*path, key_node.value)] = key_node.start_mark.line + 1
                _collect_lines(value_node, (*path, key_node.value), out)
    elif isinstance(node, yaml.SequenceNode):
        for index, item in enumerate(node.value):
            _collect_lines(item, (*path, index), out)


# ------------------------------------------------------------------------------------------
# Overrides
# ------------------------------------------------------------------------------------------
_OVERRIDE_KEY = re.compile(r"^[A-Za-z_]\w*(\.[A-Za-z_]\w*)*$")


def _sub_model(model: type[BaseModel] | None, name: str) -> type[BaseModel] | None:
    if model is None or name not in model.model_fields:
        return None
    annotation = model.model_fields[name].annotation
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):  # e.g. ``tune``
        members = [a for a in typing.get_args(annotation) if a is not type(None)]
        annotation = members[0] if len(members) == 1 else None
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    return None


def _suggest(name: str, valid: Iterable[str]) -> str:
    valid = list(valid)
    close = difflib.get_close_matches(name, valid, n=1, cutoff=0.6)
    if not close and len(name) >= 3:  # abbreviations: 'totl' → 'total_timesteps'
        close = [v for v in valid if v.startswith(name[:3]) or name in v][:1]
    if close:
        return f"did you mean {close[0]!r}?"
    return "valid names: " + ", ".join(valid)


def _parse_override(text: str, root: type[BaseModel]) -> tuple[tuple[str, ...], Any]:
    label = f"--set {text if len(text) <= 80 else text[:77] + '...'}"
    key, sep, raw = text.partition("=")
    key = key.strip()
    if not sep or not _OVERRIDE_KEY.match(key):
        raise SpecError(
            label,
            "malformed override",
            "write it as dotted.path=value, e.g. training.total_timesteps=2000",
        )
    parts = tuple(key.split("."))
    model: type[BaseModel] | None = root
    for depth, part in enumerate(parts):
        where = ".".join(parts[:depth])
        if model is None:
            raise SpecError(
                label,
                f"{where!r} has no sub-fields",
                f"set the whole value instead, e.g. {where}=[...]",
                field=key,
            )
        if part not in model.model_fields:
            raise SpecError(
                label, f"unknown field {part!r}", _suggest(part, model.model_fields), field=key
            )
        model = _sub_model(model, part)
    _check_yaml_size(raw, label)
    try:
        value = yaml.load(raw, Loader=_Loader) if raw.strip() else None
    except (yaml.YAMLError, RecursionError) as exc:
        problem = getattr(exc, "problem", None) or str(exc)
        raise SpecError(
            label,
            f"value is not valid YAML ({problem})",
            "quote it for the shell, e.g. --set 'seeds=[0, 1]'",
            field=key,
        ) from None
    return parts, value


def _apply_override(data: dict[str, Any], parts: tuple[str, ...], value: Any, label: str) -> None:
    node = data
    for depth, part in enumerate(parts[:-1]):
        child = node.get(part)
        if child is None:
            child = node[part] = {}
        if not isinstance(child, dict):
            raise SpecError(
                label,
                f"cannot set inside {'.'.join(parts[: depth + 1])}: the spec gives it a "
                f"{type(child).__name__}, not a mapping",
                "fix that key in the file",
                field=".".join(parts),
            )
        node = child
    node[parts[-1]] = value


# ------------------------------------------------------------------------------------------
# ValidationError → SpecError
# ------------------------------------------------------------------------------------------
_TYPE_TAG = re.compile(
    r"^(int|float|str|bool|none|list|dict|tuple|.*\[.*\]|function-.*|constrained-.*)$"
)


def _clean_loc(
    loc: Sequence[Any], root: type[BaseModel], extra: str | tuple[str, ...] = ""
) -> tuple[Any, ...]:
    """Drop pydantic's union-member tags from an error location (fields of ``root``); append
    ``extra`` (dotted, or the parts themselves when a part holds a dot)."""
    out: list[Any] = []
    model: type[BaseModel] | None = root
    for part in loc:
        if model is not None and isinstance(part, str) and part in model.model_fields:
            out.append(part)
            model = _sub_model(model, part)
            continue
        if isinstance(part, str) and _TYPE_TAG.match(part):
            continue
        out.append(part)
        model = None
    if extra:
        out.extend(extra.split(".") if isinstance(extra, str) else extra)
    return tuple(out)


def _format_loc(loc: Sequence[Any]) -> str:
    text = ""
    for part in loc:
        text += f"[{part}]" if isinstance(part, int) else (f".{part}" if text else str(part))
    return text or "(top level)"


def _model_for(loc: Sequence[Any], root: type[BaseModel]) -> type[BaseModel] | None:
    model: type[BaseModel] | None = root
    for part in loc:
        model = _sub_model(model, part) if isinstance(part, str) else None
    return model


def _short(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 40 else text[:37] + "..."


def _describe(error: ErrorDetails, loc: tuple[Any, ...], root: type[BaseModel]) -> tuple[str, str]:
    """(problem, fix) for one pydantic error."""
    kind, ctx, value = error["type"], error.get("ctx") or {}, error.get("input")
    msg = error["msg"]
    if kind in (ERROR_TYPE, "value_error", "assertion_error"):  # a validator's own words
        text = ctx.get("message", re.sub(r"^(Value|Assertion) error, ", "", msg))
        problem, _, fix = str(text).partition("; ")
        return problem, fix or "fix the value (see `softtrack spec --schema`)"
    if kind == "extra_forbidden":
        parent = _model_for(loc[:-1], root)
        name = str(loc[-1])
        if parent is None:
            return f"unknown field {name!r}", "remove it"
        valid = [*parent.model_fields, *(["base"] if len(loc) == 1 else [])]  # bases.BASE_KEY
        return f"unknown field {name!r}", _suggest(name, valid)
    if kind == "missing":
        if loc and isinstance(loc[-1], int):
            return f"item [{loc[-1]}] is missing", "give all the values, e.g. [x, y, z]"
        return "required field is missing", "add it"
    if kind == "literal_error":
        fix = f"use {ctx.get('expected', 'one of the listed values')}"
        if isinstance(value, str):
            options = re.findall(r"'([^']*)'", str(ctx.get("expected", "")))
            close = difflib.get_close_matches(value, options, n=1, cutoff=0.6)
            if close:
                fix = f"did you mean {close[0]!r}? ({fix})"
        return f"invalid value {_short(value)}", fix
    bounds = {
        "greater_than": ">",
        "greater_than_equal": "≥",
        "less_than": "<",
        "less_than_equal": "≤",
    }
    if kind in bounds:
        bound = next(iter(ctx.values()), "?")
        return f"{_short(value)} is out of range", f"use a value {bounds[kind]} {bound}"
    if kind in ("int_type", "int_parsing", "int_from_float"):
        return (
            f"expected a whole number, got {_short(value)} ({type(value).__name__})",
            "write e.g. 100000 or 1e5",
        )
    if kind in ("float_type", "float_parsing", "finite_number"):
        return (
            f"expected a finite number, got {_short(value)}",
            "write e.g. 0.001 or 1.0e-3",
        )
    if kind in ("bool_type", "bool_parsing"):
        return f"expected true or false, got {_short(value)}", "write true or false"
    if kind in ("string_type", "string_pattern_mismatch"):
        if loc == ("name",):
            return (
                f"invalid name {_short(value)}",
                "use 1–64 letters, digits, '_', '-' or '.', starting with a letter or digit",
            )
        return f"expected text, got {_short(value)}", "write a string"
    if kind in ("list_type", "tuple_type"):
        return f"expected a list, got {_short(value)}", "write it as [a, b, ...]"
    if kind in ("model_type", "dict_type", "model_attributes_type"):
        return (
            f"expected a mapping of fields, got {_short(value)}",
            "write its fields indented under the key (see `softtrack spec --defaults`)",
        )
    if kind in ("too_short", "too_long"):
        return msg, "give the right number of values"
    return f"{msg} (got {_short(value)})", "fix the value (see `softtrack spec --schema`)"


def _convert(
    exc: ValidationError,
    root: type[BaseModel],
    label: str,
    lines: dict[tuple[Any, ...], int],
    overrides: dict[tuple[str, ...], str],
    files: dict[tuple[Any, ...], str] | None = None,
) -> SpecError:
    """The first error of ``exc`` (validating ``root``) as a SpecError; ``lines``/``files`` give
    the line and the file (of a ``base:`` chain; default ``label``) of each field path."""
    errors = exc.errors()
    locs: list[tuple[Any, ...]] = []
    for err in errors:
        extra = (err.get("ctx") or {}).get("field", "") if err["type"] == ERROR_TYPE else ""
        locs.append(_clean_loc(err["loc"], root, extra))
    first, loc = errors[0], locs[0]
    problem, fix = _describe(first, loc, root)
    n_more = len(set(locs)) - 1
    if n_more > 0:
        fix = (fix + " " if fix else "") + f"(and {n_more} more error{'s' if n_more > 1 else ''})"
    source, line = label, None
    for parts, raw in overrides.items():
        if loc[: len(parts)] == parts:
            source = f"--set {raw}"
            break
    else:
        for depth in range(len(loc), 0, -1):
            if loc[:depth] in lines:
                line = lines[loc[:depth]]
                source = (files or {}).get(loc[:depth], label)
                break
        if overrides:
            source += " (with " + ", ".join(f"--set {raw}" for raw in overrides.values()) + ")"
    return SpecError(source, problem, fix, field=_format_loc(loc), line=line)
