"""Pieces shared by the subcommands' argument parsers: the usage error, the help layout and
the argument types (each raises ``argparse.ArgumentTypeError`` with the reason)."""

from __future__ import annotations

import argparse
import math
import textwrap
from collections.abc import Callable


class UsageError(Exception):
    """A bad command-line argument: reported on one line, exit status 2."""


#: help layout of every parser: the epilogs keep their own line breaks
FORMATTER = argparse.RawDescriptionHelpFormatter


def fill(text: str) -> str:
    """Wrap a description (the raw formatter keeps the epilogs' own line breaks)."""
    return textwrap.fill(text, width=88)


def positive_float(what: str) -> Callable[[str], float]:
    """An argument type for a finite number > 0; ``what`` (the option) heads its messages."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{what} must be a number, got {text!r}") from None
        if not math.isfinite(value) or value <= 0:
            raise argparse.ArgumentTypeError(f"{what} must be greater than 0, got {text!r}")
        return value

    return parse


def non_negative_float(text: str) -> float:
    """A finite number >= 0."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number, got {text!r}") from None
    if not math.isfinite(value) or value < 0:
        raise argparse.ArgumentTypeError(f"must be 0 or more, got {text!r}")
    return value


def fraction(text: str) -> float:
    """A number from 0 to 1."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a number from 0 to 1, got {text!r}") from None
    if not math.isfinite(value) or not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"must be from 0 to 1, got {text!r}")
    return value


def seed(text: str) -> int:
    """A whole number >= 0 (a random seed)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be a whole number, got {text!r}") from None
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be 0 or more, got {text!r}")
    return value

