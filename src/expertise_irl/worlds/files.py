"""Files of both worlds' maps: the text map's path and the settings TOML beside it."""

from __future__ import annotations

import math
import tomllib
from pathlib import Path

from ..errors import InputError, read_text


def map_file(path: str | Path, noun: str) -> Path:
    """``path`` as a :class:`Path`; raises :class:`InputError` unless it is a file."""
    path = Path(path)
    if not path.is_file():
        raise InputError(f"{path}: no such {noun} file")
    return path


def read_toml(path: Path, text: str | None = None) -> dict:
    """The table of a map's settings TOML; ``text`` is its content when already read."""
    if text is None:
        text = read_text(path)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise InputError(f"{path}: invalid TOML ({exc})") from None


def check_known(path: Path, key: str, known) -> None:
    """Refuse a setting not in ``known``."""
    if key not in known:
        raise InputError(f"{path}: unknown setting {key!r} (known: {', '.join(known)})")


def number_setting(path: Path, key: str, value) -> float:
    """A numeric setting as a float; a bool or a non-number raises :class:`InputError`."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(f"{path}: setting {key!r} must be a number, got {value!r}")
    return float(value)


def check_goal_settings(path: Path, settings: dict) -> None:
    """Refuse a ``gamma`` outside (0, 1) and a ``goal_bonus`` that is not finite."""
    if "gamma" in settings and not 0.0 < settings["gamma"] < 1.0:
        raise InputError(f"{path}: gamma must be in (0, 1), got {settings['gamma']:g}")
    if "goal_bonus" in settings and not math.isfinite(settings["goal_bonus"]):
        raise InputError(f"{path}: goal_bonus must be a finite number")
