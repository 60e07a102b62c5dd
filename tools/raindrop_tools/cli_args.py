"""Argument types shared by the tools' command lines."""

from __future__ import annotations

import argparse


def at_least(minimum: int):
    """An argparse ``type``: an integer >= ``minimum``, else argparse's usage error (exit 2).
    A negative ``--limit`` used to be taken as a slice end and dropped the last samples
    silently; ``--folds 0`` divided by zero."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"{value} is less than {minimum}")
        return value

    parse.__name__ = f"integer >= {minimum}"
    return parse


def unit_interval(text: str) -> float:
    """An argparse ``type``: a number in [0, 1]. NaN compares false with everything, so a
    threshold of nan gave empty masks and a result without a word."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not 0.0 <= value <= 1.0:
        raise argparse.ArgumentTypeError(f"{text} is not in [0, 1]")
    return value


def width_x_height(text: str) -> tuple[int, int]:
    """An argparse ``type``: ``WIDTHxHEIGHT`` (e.g. 512x256), as every program of the project
    takes sizes, returned as (width, height), both >= 1."""
    try:
        w, h = (int(v) for v in text.lower().split("x"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected WIDTHxHEIGHT (e.g. 512x256), got {text!r}") from None
    if w < 1 or h < 1:
        raise argparse.ArgumentTypeError(f"width and height must be at least 1, got {text!r}")
    return w, h
