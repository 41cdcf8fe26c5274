"""Parsing ``dgt``'s argument values: coordinates (negative ones included), vehicles (a
named one or a vehicle file), a DEM's band and a heightmap's resolution."""

from __future__ import annotations

import argparse
import math
import re

from dgt_lib.core.config import VEHICLES


def vehicle_or_file(text: str) -> str:
    """``dgt plan --vehicle``: a named vehicle or a ``.toml`` vehicle file."""
    if text in VEHICLES or text.endswith(".toml"):
        return text
    raise argparse.ArgumentTypeError(f"invalid choice: {text!r} (choose from "
                                     f"{', '.join(VEHICLES)}, or a vehicle file FILE.toml)")


def floats(text: str, n: int, what: str) -> tuple[float, ...]:
    """``x,y[,yaw]`` → n finite floats; an argparse error naming the format otherwise."""
    try:
        values = tuple(float(v) for v in text.split(","))
    except ValueError:
        values = ()
    if len(values) != n or not all(math.isfinite(v) for v in values):
        names = "x,y,yaw" if n == 3 else "x,y"
        raise argparse.ArgumentTypeError(f"{what} must be {names}: finite numbers in metres "
                                         f"(yaw in radians), got {text!r}")
    return values


COORDINATE_OPTIONS: tuple[str, ...] = ("--start", "--goal")
"""Options whose value is a comma-separated list of numbers, possibly negative."""

NEGATIVE_NUMBER = re.compile(r"-\.?\d")


def glue_negative_coordinates(argv: list[str]) -> list[str]:
    """``--start -5,14,0.8`` → ``--start=-5,14,0.8``.

    argparse reads a value that starts with '-' as an option unless it is one plain
    negative number, so ``-5,14,0.8`` ended in "expected one argument". Gluing the
    value to its option is argparse's own spelling for such values; only the options
    of :data:`COORDINATE_OPTIONS` followed by a value that starts like a negative
    number are rewritten, every other argument is left as it is."""
    out: list[str] = []
    i = 0
    while i < len(argv):
        arg = argv[i]
        if (arg in COORDINATE_OPTIONS and i + 1 < len(argv)
                and NEGATIVE_NUMBER.match(argv[i + 1])):
            out.append(f"{arg}={argv[i + 1]}")
            i += 2
            continue
        if arg == "--":  # everything after it is positional: leave it alone
            out.extend(argv[i:])
            break
        out.append(arg)
        i += 1
    return out


def band_arg(text: str) -> int:
    """``--band``: a band number, 1 or more."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if not 1 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"a band is a whole number from 1, got {text!r}")
    return value


def resolution_arg(text: str) -> float:
    """``--resolution``: a heightmap's metres per pixel, within
    :data:`~dgt_lib.core.constraints.HEIGHTMAP_RESOLUTION_M`."""
    from dgt_lib.core.constraints import HEIGHTMAP_RESOLUTION_M

    low, high = HEIGHTMAP_RESOLUTION_M
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not low <= value <= high:
        raise argparse.ArgumentTypeError(f"metres per pixel in [{low:g}, {high:g}], "
                                         f"got {text!r}")
    return value
