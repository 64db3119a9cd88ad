"""``base:`` -- a spec file that extends another and states only what differs.

A spec file may name another spec file at its top level, ``base: ../study/td3-sbx-64-4e6.yaml``
(relative to the directory of the file that names it); that file may name its own base, and so
on. The chain is resolved before validation by a deep merge, the base first: mappings merge key
by key and the file that extends wins; a list or a scalar replaces the base's value as a whole.
Two keys are not inherited: ``base`` itself and ``name`` (an experiment's name identifies it in
run listings, reports and its spec hash, so a file without ``name`` is named after its own
file, never after its base). ``--set`` overrides apply after the whole chain.

Every problem (a missing base, a cycle, a base that is not a mapping, a bad key in any file of
the chain) is a one-line :class:`SpecError` naming the file, the field and the fix; validation
errors name the file of the chain that gave the offending value.
"""

from __future__ import annotations

import copy
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from softtrack.file_kinds import FileKindError, FileTooLargeError, read_regular_file
from softtrack.spec.fields import SpecError
from softtrack.spec.parsing import _parse_yaml

__all__ = ["BASE_KEY", "ResolvedSource", "read_spec_file", "resolve_spec_file"]

BASE_KEY = "base"
_NOT_INHERITED = (BASE_KEY, "name")

FieldPath = tuple[Any, ...]


@dataclass
class ResolvedSource:
    """A spec file with its ``base:`` chain merged, not yet validated.

    Attributes:
        data: the merged data (without ``base``); not a mapping only where the file itself is
            not one (``parse_spec`` reports that).
        lines: field path → 1-based line in the file that gave the value.
        files: field path → that file (as the loader names it).
        chain: the file itself, then its base, its base's base, ...
    """

    data: Any
    lines: dict[FieldPath, int] = field(default_factory=dict)
    files: dict[FieldPath, str] = field(default_factory=dict)
    chain: tuple[str, ...] = ()


def read_spec_file(path: str | os.PathLike[str]) -> tuple[Any, dict[FieldPath, int]]:
    """One YAML file: its data and a map field path → line (raises :class:`SpecError`)."""
    path = Path(path)
    label = str(path)
    if not path.exists():
        raise SpecError(
            label, "no such file", "check the path; the shipped specs are in experiments/"
        )
    if path.is_dir():
        raise SpecError(label, "is a directory, not a spec file", "give a .yaml file")
    raw = _read_regular_file(path, label)
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise SpecError(label, f"not UTF-8 text ({exc.reason})", "save the file as UTF-8") from None
    if "\x00" in text:
        raise SpecError(label, "holds NUL characters: not a text file", "give a .yaml spec file")
    return _parse_yaml(text, label)


#: The largest spec file read, bytes (the shipped ones are under 4 kB).
MAX_SPEC_BYTES = 1_000_000


def _read_regular_file(path: Path, label: str) -> bytes:
    """The bytes of a regular file of at most :data:`MAX_SPEC_BYTES`
    (:func:`~softtrack.file_kinds.read_regular_file`: a FIFO, a device or a socket is refused
    before anything is read from it); nothing of the file is ever quoted back."""
    try:
        return read_regular_file(path, MAX_SPEC_BYTES)
    except FileKindError as exc:
        raise SpecError(label, f"{exc}, not a spec file", "give a .yaml spec file") from None
    except FileTooLargeError:
        raise SpecError(
            label,
            f"is larger than {MAX_SPEC_BYTES // 1000} kB: not a spec file",
            "give a .yaml spec file (a spec is a few kB)",
        ) from None
    except OSError as exc:
        raise SpecError(
            label, f"cannot read the file ({exc.strerror})", "check its permissions"
        ) from None


def _base_path(label: str, data: dict[str, Any], lines: dict[FieldPath, int]) -> str:
    """The base file named by ``data['base']``, relative to the directory of ``label``."""
    value, line = data[BASE_KEY], lines.get((BASE_KEY,))
    if not isinstance(value, str) or not value.strip():
        raise SpecError(
            label,
            f"expected the path of another spec file, got {value!r}",
            "write e.g. base: ../study/td3-sbx-64-4e6.yaml (relative to this file's directory)",
            field=BASE_KEY,
            line=line,
        )
    return os.path.normpath(os.path.join(os.path.dirname(label), value.strip()))


def _check_base_file(
    label: str, base: str, data: dict[str, Any], lines: dict[FieldPath, int]
) -> None:
    line = lines.get((BASE_KEY,))
    target = Path(base)
    if not target.exists() or target.is_dir():
        problem = "is a directory, not a spec file" if target.is_dir() else "no such file"
        raise SpecError(
            label,
            f"{data[BASE_KEY]!r} ({base}): {problem}",
            "give the path of a spec file relative to this file's directory",
            field=BASE_KEY,
            line=line,
        )


def _merge(base: dict[str, Any], child: dict[str, Any]) -> dict[str, Any]:
    """Deep merge: mappings merge key by key, ``child`` wins; anything else replaces."""
    out = dict(base)
    for key, value in child.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], value)
        else:
            out[key] = copy.deepcopy(value)
    return out


def _paths(data: Any, prefix: FieldPath = ()) -> set[FieldPath]:
    """Every field path present in ``data`` (mapping keys and list indices)."""
    out = {prefix}
    if isinstance(data, dict):
        for key, value in data.items():
            out |= _paths(value, (*prefix, key))
    elif isinstance(data, list):
        for index, value in enumerate(data):
            out |= _paths(value, (*prefix, index))
    return out


def resolve_spec_file(path: str | os.PathLike[str]) -> ResolvedSource:
    """Read a spec file and the chain of files its ``base:`` goes through, and merge them.

    Raises:
        SpecError: a file of the chain is missing, unreadable or malformed; a ``base`` is not a
            path, names a missing file or closes a cycle; a base file's top level is not a
            mapping.
    """
    label = str(path)
    data, lines = read_spec_file(path)
    layers: list[tuple[str, dict[str, Any], dict[FieldPath, int]]] = []
    seen: dict[str, str] = {}  # real path → label, to find cycles
    while True:
        if not isinstance(data, dict):
            if not layers:  # the file itself: parse_spec reports it with its usual fix
                return ResolvedSource(data, lines, {}, (label,))
            child = layers[-1][0]
            got = "an empty document" if data is None else f"a {type(data).__name__}"
            raise SpecError(
                label,
                f"the top level must be a mapping of sections, got {got} (it is the base of "
                f"{child})",
                "make it a spec file, or point base: in that file at one",
                line=1 if data is not None else None,
            )
        seen[os.path.realpath(label)] = label
        layers.append((label, data, lines))
        if BASE_KEY not in data:
            break
        base = _base_path(label, data, lines)
        _check_base_file(label, base, data, lines)
        if os.path.realpath(base) in seen:
            loop = " → ".join([*(layer[0] for layer in layers), base])
            raise SpecError(
                label,
                f"{data[BASE_KEY]!r} closes a cycle: {loop}",
                "a spec cannot extend itself; remove base: from one file of the loop",
                field=BASE_KEY,
                line=lines.get((BASE_KEY,)),
            )
        label = base
        data, lines = read_spec_file(base)

    merged: dict[str, Any] = {}
    merged_lines: dict[FieldPath, int] = {}
    files: dict[FieldPath, str] = {}
    for depth, (layer_label, layer_data, layer_lines) in enumerate(reversed(layers)):
        is_child = depth == len(layers) - 1
        dropped = (BASE_KEY,) if is_child else _NOT_INHERITED
        own = {k: v for k, v in layer_data.items() if k not in dropped}
        merged = _merge(merged, own)
        for field_path, line in layer_lines.items():
            if field_path and field_path[0] in dropped:
                continue
            merged_lines[field_path] = line
            files[field_path] = layer_label
    present = _paths(merged)
    merged_lines = {p: n for p, n in merged_lines.items() if p in present and p}
    files = {p: f for p, f in files.items() if p in merged_lines}
    return ResolvedSource(merged, merged_lines, files, tuple(layer[0] for layer in layers))
