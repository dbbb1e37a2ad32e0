"""Every package declares its public names, and every public function and class is documented in
Google style, the style the API reference (mkdocstrings, ``docstring_style: google``) renders.

The public names are those of every package's ``__all__`` and the members that the pages of
``docs/api/`` list in their ``:::`` blocks. For each function or class among them:

- a docstring: a one-line summary, then a blank line before anything else;
- a function with parameters: an ``Args:`` section that names every parameter (``*args`` and
  ``**kwargs`` as written in the signature), and no parameter the signature lacks;
- a function that returns something (its return annotation is not ``None``): ``Returns:`` or
  ``Yields:``;
- a function whose own body raises an exception (a ``raise`` with an exception, outside nested
  functions): ``Raises:``;
- a class built with arguments (a dataclass's fields, an ``__init__``): ``Args:`` or
  ``Attributes:``. Enumerations and exceptions are described by their docstring alone.

Public methods of those classes that take parameters follow the rules of functions.
"""

from __future__ import annotations

import ast
import enum
import importlib
import inspect
import re
import textwrap
from pathlib import Path

import pytest

import expertise_irl

SRC = Path(expertise_irl.__file__).parent
API_PAGES = Path(__file__).resolve().parents[1] / "docs" / "api"

#: the section headers of Google-style docstrings that this test reads
_SECTION = re.compile(
    r"^(Args|Arguments|Attributes|Returns|Yields|Raises|Examples?|Notes?|Warns|See Also):\s*$", re.M)


def packages() -> list[str]:
    """Every package of ``src/expertise_irl``, by dotted name."""
    return sorted(".".join(p.relative_to(SRC.parent).parent.parts) for p in SRC.rglob("__init__.py"))


def _resolve(package: str, name: str):
    module = importlib.import_module(package)
    try:
        return getattr(module, name)
    except AttributeError:
        return importlib.import_module(f"{package}.{name}")  # a submodule named in __all__


def api_page_members() -> dict[str, object]:
    """``{"module.name": object}`` of every member a ``:::`` block of ``docs/api/*.md`` lists."""
    out = {}
    block = re.compile(r"^::: (\S+)\n((?:[ ]{4}.*\n|\n(?=[ ]{4}))*)", re.M)
    for page in sorted(API_PAGES.glob("*.md")):
        for m in block.finditer(page.read_text(encoding="utf-8")):
            members = re.search(r"members:\s*\[([^\]]*)\]", m.group(2))
            if not members:
                continue
            module = importlib.import_module(m.group(1))
            for name in (n.strip() for n in members.group(1).split(",") if n.strip()):
                out[f"{m.group(1)}.{name}"] = getattr(module, name)
    return out


def public_objects() -> dict[str, object]:
    """Every function and class that a package's ``__all__`` or an API page names."""
    found = {}
    for package in packages():
        for name in getattr(importlib.import_module(package), "__all__", []):
            found[f"{package}.{name}"] = _resolve(package, name)
    found.update(api_page_members())
    return {k: v for k, v in found.items() if inspect.isfunction(v) or inspect.isclass(v)}


def _sections(doc: str) -> dict[str, str]:
    """Section name -> its body (dedented), of a cleaned docstring."""
    heads = list(_SECTION.finditer(doc))
    return {h.group(1): textwrap.dedent(doc[h.end():heads[i + 1].start() if i + 1 < len(heads) else len(doc)])
            for i, h in enumerate(heads)}


def _documented_names(body: str) -> set[str]:
    """The names of the entries of an ``Args:`` section (``name:``, ``name (type):``)."""
    return set(re.findall(r"^(\*{0,2}\w+)(?:\s*\([^)]*\))?:", body, re.M))


def _raises_directly(func) -> bool:
    """Whether ``func``'s own body has a ``raise`` with an exception (nested functions aside)."""
    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(func)))
    except (OSError, TypeError, SyntaxError):
        return False
    (node,) = tree.body

    def walk(n):
        for child in ast.iter_child_nodes(n):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.Lambda | ast.ClassDef):
                continue
            if isinstance(child, ast.Raise) and child.exc is not None:
                return True
            if walk(child):
                return True
        return False

    return walk(node)


def _parameters(func) -> list[str]:
    """The parameters of ``func`` as an ``Args:`` section names them."""
    star = {inspect.Parameter.VAR_POSITIONAL: "*", inspect.Parameter.VAR_KEYWORD: "**"}
    return [star.get(p.kind, "") + p.name for p in inspect.signature(func).parameters.values()
            if p.name not in ("self", "cls")]


def function_problems(func) -> list[str]:
    """What ``func``'s docstring lacks (see the module's docstring); empty when nothing."""
    doc = inspect.getdoc(func)
    if not doc:
        return ["no docstring"]
    problems = []
    lines = doc.splitlines()
    if len(lines) > 1 and lines[1].strip():
        problems.append("no blank line after the one-line summary")
    sections = _sections(doc)
    params = _parameters(func)
    if params:
        if "Args" not in sections:
            problems.append(f"no Args: section for {', '.join(params)}")
        else:
            named = _documented_names(sections["Args"])
            plain = {p.lstrip("*") for p in params}
            missing = [p for p in params if p not in named and p.lstrip("*") not in named]
            extra = sorted(n for n in named if n.lstrip("*") not in plain)
            if missing:
                problems.append(f"Args: does not name {', '.join(missing)}")
            if extra:
                problems.append(f"Args: names {', '.join(extra)}, not in the signature")
    returns = inspect.signature(func).return_annotation
    if returns not in (inspect.Signature.empty, None, "None") and not {"Returns", "Yields"} & sections.keys():
        problems.append(f"no Returns: section (it returns {returns})")
    if _raises_directly(func) and "Raises" not in sections:
        problems.append("raises, with no Raises: section")
    return problems


def _takes_arguments(cls) -> bool:
    init = cls.__dict__.get("__init__")
    if init is None:
        return False
    return bool(_parameters(init))


def class_problems(cls) -> list[str]:
    """What ``cls``'s docstring and its public methods' lack; empty when nothing."""
    doc = inspect.getdoc(cls) if cls.__doc__ else None
    if not doc:
        return ["no docstring"]
    lines = doc.splitlines()
    problems = []
    if len(lines) > 1 and lines[1].strip():
        problems.append("no blank line after the one-line summary")
    if issubclass(cls, enum.Enum | BaseException):
        return problems
    if _takes_arguments(cls) and not {"Args", "Attributes"} & _sections(doc).keys():
        problems.append("built with arguments, and no Args: or Attributes: section")
    for name, member in vars(cls).items():
        func = member.__func__ if isinstance(member, staticmethod | classmethod) else member
        if name.startswith("_") or not inspect.isfunction(func) or not _parameters(func):
            continue
        problems += [f"{name}(): {p}" for p in function_problems(func)]
    return problems


def test_every_package_defines_all():
    missing = [p for p in packages() if "__all__" not in vars(importlib.import_module(p))]
    assert not missing, "packages without __all__: " + ", ".join(missing)


@pytest.mark.parametrize("package", packages())
def test_every_name_in_all_exists(package):
    module = importlib.import_module(package)
    for name in module.__all__:
        _resolve(package, name)  # raises if the name is not there


def test_the_package_root_exports_its_all():
    namespace: dict = {}
    exec("from expertise_irl import *", namespace)
    assert set(expertise_irl.__all__) <= namespace.keys()
    assert set(dir(expertise_irl)) == set(expertise_irl.__all__)


def test_every_public_function_and_class_has_google_style_sections():
    problems, seen = [], set()
    for name, obj in sorted(public_objects().items()):
        if id(obj) in seen:  # one object under several names is reported once
            continue
        seen.add(id(obj))
        found = class_problems(obj) if inspect.isclass(obj) else function_problems(obj)
        problems += [f"{name}: {p}" for p in found]
    assert not problems, "docstrings to complete:\n" + "\n".join(problems)


def test_the_checks_see_what_they_look_for():
    def documented(a, *rest, key=None, **options) -> int:
        """One line.

        Args:
            a: a.
            *rest: the rest.
            key (str): a key.
            **options: options.

        Returns:
            1.

        Raises:
            ValueError: never.
        """
        if a is None:
            raise ValueError("a")
        return 1

    def bare(a, b) -> int:
        """One line.
        Args:
            a: a.
            c: c.
        """
        raise ValueError("a")

    assert function_problems(documented) == []
    assert function_problems(bare) == [
        "no blank line after the one-line summary", "Args: does not name b",
        "Args: names c, not in the signature", "no Returns: section (it returns int)",
        "raises, with no Raises: section"]
