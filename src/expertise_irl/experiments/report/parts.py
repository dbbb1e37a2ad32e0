"""The pieces a study's report is made of; :mod:`.output` writes them, :mod:`.markdown` lays them out."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any


@dataclass
class Figure:
    """A figure: ``name`` is the file stem (``fig2``), ``fig`` a matplotlib Figure."""

    name: str
    title: str
    caption: str
    fig: Any


@dataclass
class Table:
    """A table: ``display`` (strings, shown in report.md) and ``data`` (numbers, ``tables/<name>.csv``)."""

    name: str
    title: str
    caption: str
    display: Any  # pandas.DataFrame
    data: Any  # pandas.DataFrame


@dataclass
class Section:
    """A titled block of text placed after the claims (e.g. the capped episodes)."""

    title: str
    text: str
    table: Table | None = None


@dataclass
class Report:
    """Everything one study's report says."""

    study: str
    title: str
    claims: list = field(default_factory=list)  # of claims.ClaimResult
    rules: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)  # paragraphs under the header
    figures: list[Figure] = field(default_factory=list)
    tables: list[Table] = field(default_factory=list)
    sections: list[Section] = field(default_factory=list)
    people: int | None = None  # the simulated people (or instances) the rows are about
