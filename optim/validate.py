"""Checks of configuration fields, shared by every algorithm's config: each names the class, the field and what it
allows."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["check_int", "check_real", "check_positive", "check_probability", "check_bool"]


def check_int(cls: str, name: str, value, minimum: int) -> None:
    """Check that ``value`` is an integer (not a bool) ``>= minimum``.

    Args:
        cls: the config's class name, for the error.
        name: the field's name.
        value: its value.
        minimum: the smallest allowed.

    Raises:
        ValueError: ``<cls>.<name> must be an integer >= <minimum>, got <value>``.
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < minimum:
        raise ValueError(f"{cls}.{name} must be an integer >= {minimum}, got {value!r}")


def check_real(cls: str, name: str, value, lo: float | None = None, hi: float | None = None, *,
               lo_open: bool = False, hi_open: bool = False) -> None:
    """Check that ``value`` is a finite real number (not a bool) in the interval from ``lo`` to ``hi``.

    Args:
        cls: the config's class name, for the error.
        name: the field's name.
        value: its value.
        lo: the lower end, or None for none.
        hi: the upper end, or None for none.
        lo_open: exclude ``lo`` itself.
        hi_open: exclude ``hi`` itself.

    Raises:
        ValueError: naming ``<cls>.<name>`` and the interval.
    """
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{cls}.{name} must be a real number, got {value!r}") from None
    bad = not math.isfinite(x) or isinstance(value, bool)
    if lo is not None:
        bad |= x <= lo if lo_open else x < lo
    if hi is not None:
        bad |= x >= hi if hi_open else x > hi
    if bad:
        lb = "(-inf" if lo is None else ("(" if lo_open else "[") + f"{lo}"
        ub = "inf)" if hi is None else f"{hi}" + (")" if hi_open else "]")
        raise ValueError(f"{cls}.{name} must be a finite number in {lb}, {ub}, got {value!r}")


def check_positive(cls: str, name: str, value, *, allow_zero: bool = False) -> None:
    """Check that ``value`` is a finite number ``> 0`` (``>= 0`` with ``allow_zero``).

    Args:
        cls: the config's class name, for the error.
        name: the field's name.
        value: its value.
        allow_zero: accept 0.
    """
    check_real(cls, name, value, 0.0, lo_open=not allow_zero)


def check_probability(cls: str, name: str, value) -> None:
    """Check that ``value`` is a probability in ``[0, 1]``.

    Args:
        cls: the config's class name, for the error.
        name: the field's name.
        value: its value.
    """
    check_real(cls, name, value, 0.0, 1.0)


def check_bool(cls: str, name: str, value) -> None:
    """Check that ``value`` is True or False (not 0 or 1).

    Args:
        cls: the config's class name, for the error.
        name: the field's name.
        value: its value.
    """
    if not isinstance(value, bool):
        raise ValueError(f"{cls}.{name} must be True or False, got {value!r}")
