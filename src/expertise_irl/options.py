"""The choices of the package's options, each an enum with its default, defined once.

Every choice is a :class:`enum.StrEnum`, so the strings the command line and older code pass
(``"discrete"``, ``"changing"``, ``"paper-real"``) are the members themselves:
``Expertise("changing") is Expertise.CHANGING`` and ``Expertise.CHANGING == "changing"``.
:func:`choose` reads one, refusing anything else with an :class:`OptionError` that names the
field (``expertise must be one of stationary, changing, got 'sometimes'``); the command line shows
the same message with the field's flag (``--expertise must be one of ...``), see
:meth:`OptionError.message`.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from enum import StrEnum
from typing import TypeVar

from .errors import InputError


class OptionError(InputError):
    """An option's value refused; the message names the option by its field.

    ``template`` is the message with each option named as ``{field}`` (``"{tol} must be > 0"``):
    ``str(error)`` writes the field's name (``tol must be > 0``), :meth:`message` lets a caller
    write each field as it knows it (the command line: ``--tol must be > 0``).

    Attributes:
        template: the message, each field in braces.
        fields: the fields the message names.
    """

    def __init__(self, template: str, *fields: str):
        self.template, self.fields = template, fields
        super().__init__(self.message())

    def message(self, name: Callable[[str], str] | None = None) -> str:
        """The message with each field written by ``name`` (default: the field itself)."""
        return self.template.format(**{f: (name or str)(f) for f in self.fields})


def flag(field: str) -> str:
    """A field as the command line's option: ``max_hypotheses`` -> ``--max-hypotheses``."""
    return "--" + field.replace("_", "-")


class Method(StrEnum):
    """The inference methods (:mod:`expertise_irl.inference.methods`); default :attr:`DISCRETE`."""

    DISCRETE = "discrete"  # the paper's hypothesis set (Eq. 13)
    BIRL = "birl"  # Algorithm 1
    MAP = "map"  # L-BFGS on the exact gradient
    NUTS = "nuts"  # the full posterior


class Expertise(StrEnum):
    """One β for every episode (the paper's, the default) or a β per episode that may change."""

    STATIONARY = "stationary"
    CHANGING = "changing"


class Check(StrEnum):
    """Low expertise or missing features? (:mod:`~expertise_irl.inference.misspecification`)."""

    OFF = "off"
    FAST = "fast"  # posterior predictive checks (the default)
    FULL = "full"  # also a per-state reward fitted with β


class Share(StrEnum):
    """What a study participant's tasks share: one (θ, β) (the default) or one β and a θ per task."""

    BOTH = "both"
    BETA = "beta"


class Preset(StrEnum):
    """The paper's named sets of θ components and of β (:data:`~expertise_irl.hypotheses.THETA_PRESETS`)."""

    PAPER_SIM = "paper-sim"  # Sec. V: simulation
    PAPER_REAL = "paper-real"  # Sec. VIII: the real-data study


#: A study's β grid chosen from its maps' optimal values (``--betas auto``).
AUTO_BETAS = "auto"
#: The settings' name of a set that was refined (``thetas`` and ``betas`` of an adaptive result).
ADAPTIVE = "adaptive"

#: The defaults, once.
DEFAULT_METHOD = Method.DISCRETE
DEFAULT_EXPERTISE = Expertise.STATIONARY
DEFAULT_CHECK = Check.FAST
DEFAULT_SHARE = Share.BOTH
#: Θ of a named set when only B is named, and of a study (paper-real), B when only Θ is named (paper-sim).
DEFAULT_THETAS = Preset.PAPER_REAL
DEFAULT_BETAS = Preset.PAPER_SIM

E = TypeVar("E", bound=StrEnum)


def one_of(value: str, choices: Iterable[str], field: str) -> str:
    """``value`` if it is one of ``choices`` (a choice that is a name among others: an observation
    model, a prior, the methods a command takes).

    Raises:
        OptionError: naming ``field`` and the choices in order, if ``value`` is none of them.
    """
    choices = tuple(choices)
    if value not in choices:
        raise OptionError(f"{{{field}}} must be one of {', '.join(choices)}, got {value!r}", field)
    return value


def choose(kind: type[E], value: str | E, field: str) -> E:
    """``value`` as a member of ``kind``.

    Args:
        kind: the enumeration of the choices.
        value: a member, or its name.
        field: the option's name, in the message.

    Returns:
        The member.

    Raises:
        OptionError: naming ``field`` and the choices, if ``value`` is none of them.
    """
    try:
        return kind(value)
    except ValueError:
        one_of(value, (m.value for m in kind), field)
        raise  # (unreachable: one_of refuses what the enum refuses)
