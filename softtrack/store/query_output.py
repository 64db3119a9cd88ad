"""Query results as text: an aligned table, CSV or JSON (``softtrack query --format``).

The command line prints straight from DuckDB's cursor (:func:`write_cursor`): CSV and JSON
stream in batches, so a result of millions of rows needs the memory of one batch, and no
pandas is loaded. :func:`format_result` formats a DataFrame (the Python API's result) with
the same rules.
"""

from __future__ import annotations

import csv
import io
import json
import math
import textwrap
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from datetime import date, datetime, timedelta
from decimal import ROUND_HALF_EVEN, Decimal
from typing import TYPE_CHECKING, Any, Literal

if TYPE_CHECKING:
    import duckdb
    import pandas as pd

__all__ = [
    "OUTPUT_FORMATS",
    "TABLE_ROWS",
    "OutputFormat",
    "ViewInfo",
    "format_result",
    "format_rows",
    "format_views",
    "write_cursor",
]

OutputFormat = Literal["table", "csv", "json"]
OUTPUT_FORMATS: tuple[OutputFormat, ...] = ("table", "csv", "json")
#: How a column is printed: ``float`` (6 significant digits, points aligned, right-justified),
#: ``number`` (right-justified) or ``other`` (left-justified).
ColumnKind = Literal["float", "number", "other"]


@dataclass(frozen=True)
class ViewInfo:
    """A view of the results database (or a table view that is unavailable)."""

    name: str
    description: str
    #: (column name, DuckDB type), in order; empty when unavailable.
    columns: tuple[tuple[str, str], ...]
    #: runs that contribute rows (for ``runs``/``experiments``: all runs).
    runs: int
    #: why the view is unavailable (an unreadable file), else ``None``.
    error: str | None = None


_BATCH_ROWS = 10_000
#: Rows a ``--format table`` result shows; the rest are counted (``write_cursor``).
TABLE_ROWS = 10_000
_FLOAT_TYPES = ("DOUBLE", "FLOAT", "REAL", "DECIMAL")
_INTEGER_TYPES = frozenset(
    {"TINYINT", "SMALLINT", "INTEGER", "BIGINT", "HUGEINT", "UTINYINT", "USMALLINT"}
    | {"UINTEGER", "UBIGINT", "UHUGEINT"}
)


def _plain(value: Any) -> Any:
    """A NumPy value (a DataFrame's cell) as the Python value it holds; others unchanged
    (no NumPy import: `softtrack query` answers without it)."""
    if type(value).__module__ == "numpy":
        return value.tolist()
    return value


def _is_null(value: Any) -> bool:
    value = _plain(value)
    if value is None or type(value).__name__ in ("NaTType", "NAType"):
        return True
    return isinstance(value, float) and math.isnan(value)


def _significant(value: float) -> str:
    """A finite float with at most 6 significant digits, positional, trailing zeros trimmed:
    NumPy's ``format_float_positional(value, precision=6, unique=True, fractional=False,
    trim="-")`` (the shortest round-trip digits if they are few enough, else the exact
    binary value rounded half to even)."""
    if value == 0:
        return "-0" if math.copysign(1.0, value) < 0 else "0"
    shortest = Decimal(repr(value))
    exact = shortest if len(shortest.as_tuple().digits) <= 6 else Decimal(value)
    rounded = exact.quantize(Decimal(1).scaleb(exact.adjusted() - 5), rounding=ROUND_HALF_EVEN)
    text = format(rounded, "f")
    return text.rstrip("0").rstrip(".") if "." in text else text


def _json_value(value: Any) -> Any:
    """A JSON-serialisable version of a result cell (NULL, NaN and infinities → null)."""
    value = _plain(value)
    if isinstance(value, (list, tuple)):
        return [_json_value(v) for v in value]
    if isinstance(value, dict):
        return {str(k): _json_value(v) for k, v in value.items()}
    if _is_null(value):
        return None
    if isinstance(value, bool):
        return value
    if isinstance(value, int):
        return int(value)
    if isinstance(value, (float, Decimal)):
        number = float(value)
        return number if math.isfinite(number) else None
    if isinstance(value, (datetime, date)):
        return value.isoformat()
    if isinstance(value, timedelta):
        return value.total_seconds()
    if isinstance(value, bytes):
        return value.hex()
    return value if isinstance(value, str) else str(value)


def _text_value(value: Any) -> str:
    """A result cell as table text: NULL/NaN blank, floats to 6 significant digits."""
    value = _plain(value)
    if isinstance(value, (list, tuple, dict)):
        return json.dumps(_json_value(value))
    if _is_null(value):
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (float, Decimal)):
        if not math.isfinite(value):
            return str(float(value))
        return _significant(float(value))
    if isinstance(value, datetime):
        spec = (
            "seconds"
            if value.microsecond == 0
            else ("milliseconds" if value.microsecond % 1000 == 0 else "microseconds")
        )
        return value.isoformat(sep=" ", timespec=spec)
    return str(value)


def _float_cells(values: Sequence[Any]) -> list[str]:
    """A float column as text: 6 significant digits, padded to the same number of decimals
    (at most 6) so the points line up; a value that would show as 0 keeps its own digits."""
    texts = [_text_value(v) for v in values]
    decimals = [len(t.partition(".")[2]) for t in texts if t and t[-1].isdigit()]
    if not decimals:
        return texts
    places = min(max(decimals), 6)
    cells = []
    for value, text in zip(values, texts, strict=True):
        fixed = f"{float(value):.{places}f}" if text and text[-1].isdigit() else text
        cells.append(text if float(fixed or 0) == 0 and float(value or 0) != 0 else fixed)
    return cells


def _text_table(columns: Sequence[str], kinds: Sequence[ColumnKind], rows: Sequence[Any]) -> str:
    cells = [
        _float_cells([row[i] for row in rows])
        if kinds[i] == "float"
        else [_text_value(row[i]) for row in rows]
        for i in range(len(columns))
    ]
    widths = [max([len(columns[i]), *(len(c) for c in cells[i])]) for i in range(len(columns))]

    def line(values: Sequence[str]) -> str:
        return "  ".join(
            v.rjust(widths[i]) if kinds[i] != "other" else v.ljust(widths[i])
            for i, v in enumerate(values)
        ).rstrip()

    lines = [line(columns)]
    lines.extend(line([cells[i][r] for i in range(len(columns))]) for r in range(len(rows)))
    return "\n".join(lines)


def _csv_value(value: Any) -> Any:
    value = _plain(value)
    if isinstance(value, (list, tuple, dict)):
        return json.dumps(_json_value(value))
    if _is_null(value):
        return ""
    if isinstance(value, (float, Decimal)):
        return repr(float(value))
    if isinstance(value, datetime):
        return _text_value(value)
    return value


def _csv_lines(columns: Sequence[str] | None, rows: Iterable[Sequence[Any]]) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    if columns is not None:
        writer.writerow(columns)
    writer.writerows([_csv_value(v) for v in row] for row in rows)
    return buffer.getvalue()


def _json_records(columns: Sequence[str], rows: Iterable[Sequence[Any]]) -> list[str]:
    """Each row as a JSON object indented as one item of a pretty-printed array."""
    return [
        textwrap.indent(
            json.dumps(
                {c: _json_value(v) for c, v in zip(columns, row, strict=True)},
                indent=2,
                ensure_ascii=False,
            ),
            "  ",
        )
        for row in rows
    ]


def format_rows(
    columns: Sequence[str],
    kinds: Sequence[ColumnKind],
    rows: Sequence[Sequence[Any]],
    output_format: OutputFormat = "table",
) -> str:
    """Rows as text: ``table`` (aligned columns with a header; NULL is blank), ``csv`` (with a
    header) or ``json`` (an array of records; NULL/NaN → null). Lists and structs are written
    as JSON in ``table`` and ``csv``."""
    if output_format == "json":
        records = _json_records(columns, rows)
        return "[\n" + ",\n".join(records) + "\n]" if records else "[]"
    if output_format == "csv":
        return _csv_lines(columns, rows).rstrip("\n")
    if output_format == "table":
        return _text_table(columns, kinds, rows)
    raise ValueError(f"unknown output format {output_format!r}; one of {OUTPUT_FORMATS}")


def _dtype_kind(dtype: Any) -> ColumnKind:
    kind = getattr(dtype, "kind", "O")
    if kind == "f":
        return "float"
    return "number" if kind in "iuc" else "other"


def format_result(df: pd.DataFrame, output_format: OutputFormat = "table") -> str:
    """A DataFrame (a query's result) as text, as :func:`format_rows` writes it; no index."""
    columns = [str(c) for c in df.columns]
    kinds = [_dtype_kind(dtype) for dtype in df.dtypes]
    rows = list(df.itertuples(index=False, name=None))
    return format_rows(columns, kinds, rows, output_format)


def _duckdb_kind(type_name: str) -> ColumnKind:
    if type_name.startswith(_FLOAT_TYPES):
        return "float"
    return "number" if type_name in _INTEGER_TYPES else "other"


def write_cursor(
    cursor: duckdb.DuckDBPyConnection,
    output_format: OutputFormat,
    write: Callable[[str], None],
    *,
    batch_rows: int = _BATCH_ROWS,
    table_rows: int = TABLE_ROWS,
) -> int:
    """Print a DuckDB result with ``write`` (text without the final newline per call is
    joined as it comes): CSV and JSON in batches of ``batch_rows``, a table's first
    ``table_rows`` rows aligned over each other and then a line counting the rest (fetched in
    batches and dropped), so any result needs bounded memory. Returns the number of rows.

    Raises:
        duckdb.Error: the result cannot be computed (raised while fetching).
    """
    description = cursor.description or []
    columns = [str(d[0]) for d in description]
    if output_format == "table":
        rows = cursor.fetchmany(table_rows)
        more = 0
        while batch := cursor.fetchmany(batch_rows):
            more += len(batch)
        text = _text_table(columns, [_duckdb_kind(str(d[1])) for d in description], rows)
        if more:
            text += (
                f"\n… {more:,} more rows not shown (a table shows the first {table_rows:,}); "
                "--format csv or json prints every row, or add LIMIT to the query"
            )
        write(text + "\n")
        return len(rows) + more
    count = 0
    first = True
    while batch := cursor.fetchmany(batch_rows):
        if output_format == "csv":
            write(_csv_lines(columns if first else None, batch))
        else:
            records = _json_records(columns, batch)
            write(("[\n" if first else ",\n") + ",\n".join(records))
        first = False
        count += len(batch)
    if output_format == "csv" and first:
        write(_csv_lines(columns, []))
    elif output_format == "json":
        write("[]\n" if first else "\n]\n")
    return count


def format_views(views: Sequence[ViewInfo], width: int = 100) -> str:
    """The views, each with its description and columns (``name TYPE``), as text."""
    blocks = []
    for view in views:
        runs = f"{view.runs} run" + ("" if view.runs == 1 else "s")
        head = f"{view.name} ({runs}): {view.description}"
        lines = textwrap.wrap(head, width, subsequent_indent="    ")
        if view.error is not None:
            lines += textwrap.wrap(
                f"UNAVAILABLE: {view.error}", width, initial_indent="  ", subsequent_indent="    "
            )
        else:
            # break lines only between columns (\xa0: a space textwrap does not break at)
            columns = ", ".join(f"{c} {t}".replace(" ", "\xa0") for c, t in view.columns)
            lines += [
                line.replace("\xa0", " ")
                for line in textwrap.wrap(
                    columns,
                    width,
                    initial_indent="  ",
                    subsequent_indent="  ",
                    break_on_hyphens=False,
                )
            ]
        blocks.append("\n".join(lines))
    return "\n\n".join(blocks)
