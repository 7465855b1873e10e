"""What every command's arguments are built of: the parser class that reports a bad
command line as one line, the value types (each converts a flag's text and checks its
range, so a bad value is reported as one line naming it), and the output flags several
commands share."""

from __future__ import annotations

import argparse
import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, NoReturn, TypeAlias

__all__ = [
    "OneLineParser",
    "add_force",
    "add_json",
    "add_output",
    "alike",
    "degrees",
    "fraction",
    "highpass",
    "images",
    "motor_faults",
    "node_id",
    "positive_int",
    "resolution",
    "seed",
    "threshold",
    "tilt_deg",
    "zooms",
]


class OneLineParser(argparse.ArgumentParser):
    """Reports a bad command line as one line and exit status 2.

    Subcommand parsers too say ``pipemap: error:`` (not ``pipemap match: error:``):
    one prefix for every error the command reports, whichever layer found it.
    """

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"pipemap: error: {message}\n")


if TYPE_CHECKING:
    #: What ``add_subparsers`` returns; each command adds its parser to it.
    Subparsers: TypeAlias = argparse._SubParsersAction[OneLineParser]


def _checked(
    convert: Callable[[str], float], valid: Callable[[float], bool], rule: str
) -> Callable[[str], Any]:
    """An argparse type: ``convert`` the text, then demand ``valid``, else say ``rule``."""

    def parse(text: str) -> Any:
        try:
            value = convert(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
        if not valid(value):
            raise argparse.ArgumentTypeError(f"{rule}, got {text}")
        return value

    return parse


threshold = _checked(
    float, lambda v: math.isfinite(v) and -1.0 <= v <= 1.0, "threshold must be in [-1, 1]"
)
positive_int = _checked(int, lambda v: v >= 1, "must be at least 1")
seed = _checked(int, lambda v: 0 <= v < 2**63, "seed must be in [0, 2^63)")
images = _checked(int, lambda v: 2 <= v <= 72, "images per sweep must be 2..72")
resolution = _checked(int, lambda v: 16 <= v <= 4096, "resolution must be 16..4096 px")
node_id = _checked(int, lambda v: v >= 0, "a node id is an integer >= 0")
fraction = _checked(float, lambda v: 0.0 < v <= 1.0, "must be in (0, 1]")
_fov_deg = _checked(float, lambda v: 0.0 < v < 360.0, "field of view must be in (0, 360) degrees")
_zoom = _checked(float, lambda v: math.isfinite(v) and 1.0 < v <= 2.0, "not in (1, 2]")
tilt_deg = _checked(float, lambda v: math.isfinite(v) and 0.0 <= v <= 15.0, "not in [0, 15]")
obstacles = _checked(int, lambda v: v >= 0, "an obstacle count must be >= 0")
motor_faults = _checked(int, lambda v: v >= 0, "a cut-out count must be >= 0")
alike = _checked(float, lambda v: math.isfinite(v) and 0.0 <= v <= 1.0, "not in [0, 1]")
highpass = _checked(float, lambda v: math.isfinite(v) and 0.0 <= v <= 1.0, "must be in [0, 1]")


def degrees(text: str) -> float:
    """A field of view given in degrees, in (0, 360), as radians."""
    return math.radians(_fov_deg(text))


def zooms(text: str) -> tuple[float, ...]:
    """Comma-separated zoom factors, each in (1, 2]."""
    try:
        return tuple(_zoom(part) for part in text.split(","))
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"zoom factors are numbers in (1, 2], comma-separated, got {text}"
        ) from None


def add_output(
    p: argparse.ArgumentParser, *flags: str, metavar: str, helptext: str, required: bool = False
) -> None:
    """A path the command writes to (``None`` when not given); the command checks it with
    :mod:`pipemap.cli.outputs` before any work."""
    p.add_argument(*flags, required=required, default=None, metavar=metavar, help=helptext)


def add_force(p: argparse.ArgumentParser, helptext: str) -> None:
    """``--force``: each writing command's leave to replace what its outputs would overwrite."""
    p.add_argument("--force", action="store_true", help=helptext)


def add_json(p: argparse.ArgumentParser) -> None:
    """``--json``: the result as one JSON object on standard output."""
    p.add_argument("--json", action="store_true", help="print one JSON object")
