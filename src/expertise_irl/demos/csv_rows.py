"""The non-empty rows of a user's CSV file, with their line numbers, or a one-line error.

Shared by every reader of user CSVs (demonstrations, recordings), so they refuse the same
things with the same words: a directory, a missing file, malformed CSV, a file that is not
UTF-8 text, or one with no rows at all.
"""

from __future__ import annotations

import csv
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
