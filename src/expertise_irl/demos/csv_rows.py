"""The non-empty rows of a user's CSV file, with their line numbers, or a one-line error;
and the numbers in their fields.

Shared by every reader of user CSVs (demonstrations, recordings), so they refuse the same
things with the same words: a directory, a missing file, malformed CSV, a file that is not
UTF-8 text, one with no rows at all, and an empty, non-numeric or out-of-range field.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path

from ..errors import InputError, where


def read_rows(path: str | Path, *, kind: str, nothing: str) -> list[tuple[int, list[str]]]:
    """``[(line, fields)]`` of every row with a non-empty field, fields stripped.

    ``kind`` names the file in errors ("a demonstrations CSV file"); ``nothing`` what an empty
    file lacks ("no demonstrations").
    """
    path = Path(path)
    if path.is_dir():
        raise InputError(f"{where(path)}is a directory, expected {kind}")
    if not path.is_file():
        raise InputError(f"{where(path)}no such file")
    records: list[tuple[int, list[str]]] = []
    try:
        with open(path, encoding="utf-8-sig", newline="") as fh:
            reader = csv.reader(fh)
            try:
                for row in reader:
                    fields = [f.strip() for f in row]
                    if any(fields):
                        records.append((reader.line_num, fields))
            except csv.Error as exc:
                raise InputError(f"{where(path, reader.line_num + 1)}malformed CSV ({exc})") from None
    except UnicodeDecodeError:
        raise InputError(f"{where(path)}not a UTF-8 text file") from None
    if not records:
        raise InputError(f"{where(path)}{nothing}: the file is empty")
    return records


#: Bound on integer fields: far beyond any state, cell, step or episode label; keeps int64 safe.
INT_LIMIT = 2**62


def _bad(prefix: str, column: str, text: str, problem: str) -> InputError:
    return InputError(f"{prefix}column '{column}': {text!r} {problem}")


def _number(text: str, column: str, prefix: str) -> float:
    if not text:
        raise InputError(f"{prefix}column '{column}' is empty")
    try:
        return float(text)
    except ValueError:
        raise _bad(prefix, column, text, "is not a number") from None


def parse_float(text: str, column: str, prefix: str) -> float:
    """A finite number in field ``column``; errors start with ``prefix`` (``where(path, line)``)."""
    value = _number(text, column, prefix)
    if not math.isfinite(value):
        raise _bad(prefix, column, text, "is not a finite number")
    return value


def parse_int(text: str, column: str, prefix: str, *, strict: bool = False) -> int:
    """An integer below :data:`INT_LIMIT` in size in field ``column``; a whole number written
    as a float (``3.0``) counts unless ``strict``. Errors start with ``prefix``."""
    try:
        value = int(text)
    except ValueError:
        if strict and text:
            raise _bad(prefix, column, text, "is not an integer") from None
        number = _number(text, column, prefix)
        if not math.isfinite(number) or number != int(number):
            raise _bad(prefix, column, text, "is not an integer") from None
        value = int(number)
    if abs(value) >= INT_LIMIT:
        raise _bad(prefix, column, text, "is out of range")
    return value
