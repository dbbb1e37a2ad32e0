"""Griffe extension for the API reference: the library's reST conventions, read as Markdown.

The docstrings use Sphinx roles (``:func:`solve```, ``:class:`~expertise_irl.errors.InputError```)
and document module constants with ``#:`` comments. mkdocstrings renders Markdown, so without
this the roles would show as literal ``:func:`` text and the constants would have no description.

- A role becomes inline code with Sphinx's display text: ``~a.b.c`` shows ``c``, a leading ``.``
  (relative to the module) is dropped, a trailing ``()`` is kept.
- A definition list (a line ending in ``.``, its definition indented below it) loses the
  indentation, which Markdown would show as a code block; Google-style sections (``Args:``)
  end in ``:`` and are left to griffe.
- An attribute without a docstring takes the ``#:`` comment lines just above it.

The docstrings themselves are not changed; only what the site shows.
"""

from __future__ import annotations

import re
import textwrap
from typing import Any

import griffe

_ROLE = re.compile(r":(?:py:)?(?:func|class|meth|mod|data|attr|exc|obj|const):`([^`]+)`")
#: an unindented line ending in "." and the indented block right below it (blank lines inside)
_DEFINITION = re.compile(r"^(\S[^\n]*\.\n)((?:[ ]{4}[^\n]*\n|\n(?=[ ]{4}))+)", re.M)


def _display(target: str) -> str:
    target = target.strip()
    if "<" in target and target.endswith(">"):  # :func:`text <target>`
        return target.split("<", 1)[0].strip()
    if target.startswith("~"):
        return target[1:].rsplit(".", 1)[-1]
    return target.lstrip(".")


def rst_to_markdown(text: str) -> str:
    """``text`` with Sphinx roles as inline code and definition lists dedented."""
    text = _ROLE.sub(lambda m: f"`{_display(m.group(1))}`", text)
    return _DEFINITION.sub(lambda m: m.group(1) + textwrap.dedent(m.group(2)), text + "\n").rstrip("\n")


def _comment_docstring(attr: griffe.Attribute) -> str | None:
    """The ``#:`` comment lines directly above ``attr``'s definition, or None."""
    module = attr.module
    lines = module.lines
    if not lines or attr.lineno is None:
        return None
    found: list[str] = []
    i = attr.lineno - 2  # the line above the definition, 0-based
    while i >= 0 and lines[i].lstrip().startswith("#:"):
        found.append(lines[i].lstrip()[2:].strip())
        i -= 1
    return " ".join(reversed(found)) or None


class RstRoles(griffe.Extension):
    """Sphinx roles and definition lists as Markdown; ``#:`` comments as attribute docstrings."""

    def on_object(self, *, obj: griffe.Object, loader: griffe.GriffeLoader, **kwargs: Any) -> None:
        if obj.is_alias:
            return
        if obj.docstring is None and obj.is_attribute:
            text = _comment_docstring(obj)  # type: ignore[arg-type]
            if text:
                obj.docstring = griffe.Docstring(text, lineno=obj.lineno, parent=obj)
        if obj.docstring is not None:
            obj.docstring.value = rst_to_markdown(obj.docstring.value)
