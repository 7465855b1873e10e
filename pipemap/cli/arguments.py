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
    "RangeHelpFormatter",
    "add_force",
    "add_json",
    "add_output",
    "add_verbose",
    "alike",
    "degrees",
    "downsample",
    "fraction",
    "highpass",
    "images",
    "max_rate",
    "motor_faults",
    "node_id",
    "odometry_drift",
    "positive_int",
    "resolution",
    "seed",
    "threshold",
    "tilt_deg",
    "zooms",
]


class RangeHelpFormatter(argparse.HelpFormatter):
    """Help that shows each checked flag's valid range (``[16..4096]``), taken from its
    value type (see :func:`_checked`), so that the range is written once."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help
        span = getattr(action.type, "span", None)
        if text is not None and span is not None:
            text = f"{text} [{span}]"
        return text


class OneLineParser(argparse.ArgumentParser):
    """Reports a bad command line as one line and exit status 2.

    Subcommand parsers too say ``pipemap: error:`` (not ``pipemap match: error:``):
    one prefix for every error the command reports, whichever layer found it.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("formatter_class", RangeHelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"pipemap: error: {message}\n")


if TYPE_CHECKING:
    #: What ``add_subparsers`` returns; each command adds its parser to it.
    Subparsers: TypeAlias = argparse._SubParsersAction[OneLineParser]


def _checked(
    convert: Callable[[str], float], valid: Callable[[float], bool], rule: str, span: str
) -> Callable[[str], Any]:
    """An argparse type: ``convert`` the text, then demand ``valid``, else say ``rule``.
    ``span`` is the valid range as ``--help`` shows it."""

    def parse(text: str) -> Any:
        try:
            value = convert(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
        if not valid(value):
            raise argparse.ArgumentTypeError(f"{rule}, got {text}")
        return value

    parse.span = span  # type: ignore[attr-defined]
    return parse


threshold = _checked(
    float, lambda v: math.isfinite(v) and -1.0 <= v <= 1.0, "threshold must be in [-1, 1]", "-1..1"
)
positive_int = _checked(int, lambda v: v >= 1, "must be at least 1", ">= 1")
seed = _checked(int, lambda v: 0 <= v < 2**63, "seed must be in [0, 2^63)", "0..2^63-1")
images = _checked(int, lambda v: 2 <= v <= 72, "images per sweep must be 2..72", "2..72")
resolution = _checked(
    int, lambda v: 16 <= v <= 4096, "resolution must be 16..4096 px", "16..4096 px"
)
#: ``--downsample``: the refinement's factor; more than half the largest image leaves
#: less than two pixels of any (the localizer checks each image's own size too).
downsample = _checked(int, lambda v: 1 <= v <= 2048, "must be 1..2048", "1..2048")
node_id = _checked(int, lambda v: v >= 0, "a node id is an integer >= 0", ">= 0")
fraction = _checked(float, lambda v: 0.0 < v <= 1.0, "must be in (0, 1]", "(0, 1]")
_fov_deg = _checked(
    float,
    lambda v: 0.0 < v < 360.0,
    "field of view must be in (0, 360) degrees",
    "(0, 360) degrees",
)
_zoom = _checked(float, lambda v: math.isfinite(v) and 1.0 < v <= 2.0, "not in (1, 2]", "(1, 2]")
tilt_deg = _checked(
    float, lambda v: math.isfinite(v) and 0.0 <= v <= 15.0, "not in [0, 15]", "0..15 degrees"
)
obstacles = _checked(int, lambda v: v >= 0, "an obstacle count must be >= 0", ">= 0")
motor_faults = _checked(int, lambda v: v >= 0, "a cut-out count must be >= 0", ">= 0")
highpass = _checked(
    float, lambda v: math.isfinite(v) and 0.0 <= v <= 1.0, "must be in [0, 1]", "0..1"
)
jpeg_quality = _checked(int, lambda v: 1 <= v <= 100, "JPEG quality must be 1..100", "1..100")
#: ``view --max-rate``: messages a second of each high-rate stream (0: all of them).
max_rate = _checked(
    float, lambda v: math.isfinite(v) and v >= 0.0, "a rate must be >= 0 Hz", ">= 0 Hz"
)
alike = _checked(float, lambda v: math.isfinite(v) and 0.0 <= v <= 1.0, "not in [0, 1]", "0..1")
odometry_drift = _checked(
    float, lambda v: math.isfinite(v) and 1.0 <= v <= 10.0, "not in [1, 10]", "1..10"
)


def degrees(text: str) -> float:
    """A field of view given in degrees, in (0, 360), as radians."""
    return math.radians(_fov_deg(text))


degrees.span = _fov_deg.span  # type: ignore[attr-defined]


def zooms(text: str) -> tuple[float, ...]:
    """Comma-separated zoom factors, each in (1, 2]."""
    try:
        return tuple(_zoom(part) for part in text.split(","))
    except argparse.ArgumentTypeError:
        raise argparse.ArgumentTypeError(
            f"zoom factors are numbers in (1, 2], comma-separated, got {text}"
        ) from None


zooms.span = "each in (1, 2]"  # type: ignore[attr-defined]


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


#: ``-v``'s help, the same before and after the command.
VERBOSE_HELP = "print each decision as it is made (replay, score, record, map) to stderr"


def add_verbose(p: argparse.ArgumentParser, top: bool = False) -> None:
    """``-v``/``--verbose``: before the command (``top``) or after it. After it, the flag
    has no default of its own, so that it leaves one given before the command as it is."""
    p.add_argument(
        "-v",
        "--verbose",
        action="store_true",
        default=False if top else argparse.SUPPRESS,
        help=VERBOSE_HELP,
    )
