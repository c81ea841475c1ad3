"""Pieces shared by the subcommands' argument parsers: the usage error, the help layout and
the argument types (each raises ``argparse.ArgumentTypeError`` with the reason)."""

from __future__ import annotations

import argparse
import math
import re
import textwrap
from collections.abc import Callable


class UsageError(Exception):
    """A bad command-line argument: reported on one line, exit status 2."""


#: options whose values may start with '-' (a negative axis)
SIGNED_AXIS_OPTIONS = ("--up", "--open-plane", "--window")


class Parser(argparse.ArgumentParser):
    """argparse's parser, whose "expected one argument" for an axis option says how to give
    a negative axis (``--up -y`` reads -y as an option)."""

    def error(self, message: str):
        match = re.match(r"argument (\S+): expected one argument$", message)
        if match and match.group(1) in SIGNED_AXIS_OPTIONS:
            message += (f" (a negative axis is written with '=': {match.group(1)}=-y)")
        super().error(message)


#: help layout of every parser: the epilogs keep their own line breaks
FORMATTER = argparse.RawDescriptionHelpFormatter


def fill(text: str) -> str:
    """Wrap a description (the raw formatter keeps the epilogs' own line breaks)."""
    return textwrap.fill(text, width=88)


def _number(text: str, cast: Callable[[str], float], ok: Callable[[float], bool],
            not_a_number: str, out_of_range: str) -> float:
    """`cast(text)` if `ok` accepts it, else ``argparse.ArgumentTypeError`` with the message
    for text that is not a number or for a number out of range ("..., got 'text'")."""
    try:
        value = cast(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{not_a_number}, got {text!r}") from None
    if not ok(value):
        raise argparse.ArgumentTypeError(f"{out_of_range}, got {text!r}")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0 (argparse names the option before the message)."""
    return _number(text, float, lambda v: math.isfinite(v) and v > 0, "must be a number",
                   "must be a finite number greater than 0")


def non_negative_float(text: str) -> float:
    """A finite number >= 0."""
    return _number(text, float, lambda v: math.isfinite(v) and v >= 0, "must be a number",
                   "must be a finite number, 0 or more")


def fraction(text: str) -> float:
    """A number from 0 to 1."""
    return _number(text, float, lambda v: math.isfinite(v) and 0.0 <= v <= 1.0,
                   "must be a number from 0 to 1", "must be from 0 to 1")


def seed(text: str) -> int:
    """A whole number >= 0 (a random seed)."""
    return int(_number(text, int, lambda v: v >= 0, "must be a whole number",
                       "must be 0 or more"))


def add_command(sub: argparse._SubParsersAction, name: str, *, help: str, description: str,
                epilog: str) -> argparse.ArgumentParser:
    """A subcommand's parser with the shared layout: wrapped description, raw epilog."""
    return sub.add_parser(name, help=help, description=fill(description), epilog=epilog,
                          formatter_class=FORMATTER)

