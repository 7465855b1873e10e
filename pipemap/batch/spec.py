"""A batch's SPEC: a TOML grid of runs, validated whole before any run starts.

A SPEC holds one table ``[grid]`` (or several, ``[[grid]]``, whose runs are joined)
whose keys each hold a list; the runs are the Cartesian product of the lists. Every
key is optional and stands for a ``pipemap record`` or ``pipemap score`` setting;
a key left out takes that command's default::

    description = "loop networks, both rules"   # optional

    [grid]
    network = ["paper", "random:8"]   # record --network       (default "paper")
    seed = [0, 1]                     # record --seed          (0)
    start = ["S"]                     # record --start         (the network's entry)
    condition = ["autonomous"]        # record --condition     (autonomous)
    resolution = [64]                 # record --resolution    (400)
    images = [6]                      # record --images        (6)
    align_sweeps = [true]             # record --[no-]align-sweeps (true)
    explore = ["map", "right-hand"]   # record --explore       (map)
    obstacles = [0, 3]                # record --obstacles     (0; autonomous runs only)
    motor_faults = [0, 3]             # record --motor-faults  (0; autonomous runs only)
    tilt_deg = [0, 3]                 # record --tilt-deg      (0)
    lighting = ["lamp", "even"]       # record --lighting      (lamp)
    alike = [0, 0.5, 1]               # record --alike         (0)
    odometry_drift = [1, 10]          # record --odometry-drift (1)
    rule = ["default", "paper"]       # score's decision rule  (default), see RULES
    threshold = [0.36]                # score --threshold      (the rule's own, 0.36)

Runs that differ only in ``rule`` or ``threshold`` are scored from one recording:
those two settings change the replay, not the run (``record``'s online localizer
keeps its default threshold, as ``pipemap record`` without ``--threshold`` does).

:func:`parse_spec` reports every mistake at once, one line each, as a
:class:`SpecError`; nothing here runs anything.
"""

from __future__ import annotations

import itertools
import math
import re
import tomllib
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from pipemap.batch.rules import RULES, Rule
from pipemap.defaults import IMAGES_PER_SWEEP, LAMP_STRENGTHS, LIGHTING, RESOLUTION_PX, SEED
from pipemap.errors import InputError, SimError
from pipemap.localizer.presets import PAPER_THRESHOLD

if TYPE_CHECKING:
    from pipemap.recorder import RecordSettings

__all__ = [
    "CONDITIONS",
    "DEFAULTS",
    "GRID_KEYS",
    "RULES",
    "BatchSpec",
    "Rule",
    "RunPoint",
    "SpecError",
    "load_spec",
    "parse_spec",
]

#: The grid's keys, in the order of the results' columns and of the product's loops
#: (``network`` outermost, the scoring settings innermost: the runs of one recording
#: are neighbours).
GRID_KEYS = (
    "network",
    "seed",
    "start",
    "condition",
    "resolution",
    "images",
    "align_sweeps",
    "explore",
    "obstacles",
    "motor_faults",
    "tilt_deg",
    "lighting",
    "alike",
    "odometry_drift",
    "rule",
    "threshold",
)
#: The keys that change the recording; the others change only the scoring.
RECORDING_KEYS = GRID_KEYS[:14]
CONDITIONS = ("perfect", "noise", "active", "entrance", "autonomous")
#: ``record --explore``: how the autonomous robot chooses its exits.
EXPLORE_POLICIES = ("map", "right-hand")
#: ``record --lighting``: the robot's lamp, or every surface lit evenly.
LIGHTINGS = tuple(LAMP_STRENGTHS)
#: The default of each key (``None``: resolved per run, see :class:`RunPoint`).
DEFAULTS: dict[str, Any] = {
    "network": "paper",
    "seed": SEED,
    "start": None,
    "condition": "autonomous",
    "resolution": RESOLUTION_PX,
    "images": IMAGES_PER_SWEEP,
    "align_sweeps": True,
    "explore": "map",
    "obstacles": 0,
    "motor_faults": 0,
    "tilt_deg": 0.0,
    "lighting": LIGHTING,
    "alike": 0.0,
    "odometry_drift": 1.0,
    "rule": "default",
    "threshold": None,
}
#: ``pipemap score``'s threshold when none is given (without ``--robust``).
SCORE_THRESHOLD = PAPER_THRESHOLD


class SpecError(InputError):
    """A SPEC with mistakes; ``str()`` gives one line per mistake."""

    def __init__(self, name: str, mistakes: Sequence[str]) -> None:
        self.mistakes = tuple(mistakes)
        super().__init__("\n".join(f"{name}: {m}" for m in self.mistakes))


@dataclass(frozen=True)
class RunPoint:
    """One run of the grid: every setting, defaults resolved."""

    network: str
    seed: int
    start: str
    condition: str
    resolution: int
    images: int
    align_sweeps: bool
    explore: str
    obstacles: int
    motor_faults: int
    tilt_deg: float
    lighting: str
    alike: float
    odometry_drift: float
    rule: str
    threshold: float

    @property
    def run_id(self) -> str:
        """A stable name made of the settings (the folder under ``runs/``). The
        settings of real conditions appear only when not at their default, so that a
        run's name is what it was before they were keys."""
        parts = [
            self.network,
            f"seed{self.seed}",
            self.start,
            self.condition,
            f"{self.resolution}px",
            f"{self.images}img",
            "aligned" if self.align_sweeps else "straight",
            self.explore,
            *([f"obs{self.obstacles}"] if self.obstacles else []),
            *([f"motor{self.motor_faults}"] if self.motor_faults else []),
            *([f"tilt{self.tilt_deg!r}"] if self.tilt_deg else []),
            *([self.lighting] if self.lighting != DEFAULTS["lighting"] else []),
            *([f"alike{self.alike!r}"] if self.alike else []),
            *([f"drift{self.odometry_drift!r}"] if self.odometry_drift != 1 else []),
            self.rule,
            f"t{self.threshold!r}",
        ]
        return "-".join(re.sub(r"[^A-Za-z0-9._-]", "", p) for p in parts)

    @property
    def recording_key(self) -> tuple[Any, ...]:
        """The settings of the recording: runs with the same key share one log."""
        return tuple(getattr(self, k) for k in RECORDING_KEYS)

    def settings(self) -> dict[str, Any]:
        """The grid keys and their values, in :data:`GRID_KEYS` order."""
        return {k: getattr(self, k) for k in GRID_KEYS}

    def record_settings(self) -> RecordSettings:
        """What ``pipemap record`` is given for this run."""
        from pipemap.recorder import Explore, RecordSettings
        from pipemap.sim.episode import Condition

        return RecordSettings(
            network=self.network,
            start=self.start,
            seed=self.seed,
            condition=Condition(self.condition),
            resolution_px=self.resolution,
            images_per_sweep=self.images,
            align_sweeps=self.align_sweeps,
            explore=Explore(self.explore),
            obstacles=self.obstacles,
            motor_faults=self.motor_faults,
            tilt_rad=math.radians(self.tilt_deg),
            lamp_strength=LAMP_STRENGTHS[self.lighting],
            alike=float(self.alike),
            odometry_drift=float(self.odometry_drift),
        )

    def commands(self, log: str = "run.mcap") -> tuple[str, str]:
        """The two commands that make this run by hand: record, then score."""
        record = (
            f"pipemap record --network {self.network} --seed {self.seed} --start {self.start} "
            f"--condition {self.condition} --resolution {self.resolution} "
            f"--images {self.images}{'' if self.align_sweeps else ' --no-align-sweeps'} "
            f"--explore {self.explore}"
            f"{f' --obstacles {self.obstacles}' if self.obstacles else ''}"
            f"{f' --motor-faults {self.motor_faults}' if self.motor_faults else ''}"
            f"{f' --tilt-deg {self.tilt_deg:g}' if self.tilt_deg else ''}"
            f"{f' --lighting {self.lighting}' if self.lighting != 'lamp' else ''}"
            f"{f' --alike {self.alike:g}' if self.alike else ''}"
            f"{f' --odometry-drift {self.odometry_drift:g}' if self.odometry_drift != 1 else ''}"
            f" -o {log}"
        )
        score = f"{RULES[self.rule].command()} {log} --threshold {self.threshold:g} --json"
        return record, score


@dataclass(frozen=True)
class BatchSpec:
    """A validated SPEC: its runs, in grid order, each once."""

    name: str
    text: str
    description: str
    points: tuple[RunPoint, ...]

    @property
    def varying(self) -> tuple[str, ...]:
        """The grid keys that take more than one value over the runs."""
        return tuple(k for k in GRID_KEYS if len({getattr(p, k) for p in self.points}) > 1)

    def recordings(self) -> int:
        """How many distinct recordings the runs need."""
        return len({p.recording_key for p in self.points})


# --------------------------------------------------------------------- checking


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _check_value(key: str, v: Any) -> str | None:
    """Why ``v`` cannot be a value of ``key``, or ``None`` if it can."""
    if key in ("network", "start", "condition", "rule", "explore", "lighting"):
        if not isinstance(v, str) or not v.strip():
            return f"{v!r} is not a name (a quoted string)"
        if key == "condition" and v not in CONDITIONS:
            return f"unknown condition {v!r} (one of {', '.join(CONDITIONS)})"
        if key == "lighting" and v not in LIGHTINGS:
            return f"unknown lighting {v!r} (one of {', '.join(LIGHTINGS)})"
        if key == "explore" and v not in EXPLORE_POLICIES:
            return f"unknown exploration {v!r} (one of {', '.join(EXPLORE_POLICIES)})"
        if key == "rule" and v not in RULES:
            return f"unknown rule {v!r} (one of {', '.join(RULES)})"
        return None
    if key == "align_sweeps":
        return None if isinstance(v, bool) else f"{v!r} is not true or false"
    if key in ("threshold", "tilt_deg", "alike", "odometry_drift"):
        lo, hi, what = {
            "threshold": (-1.0, 1.0, "a threshold"),
            "tilt_deg": (0.0, 15.0, "a tilt"),
            "alike": (0.0, 1.0, "a fraction"),
            "odometry_drift": (1.0, 10.0, "a drift factor"),
        }[key]
        ok = isinstance(v, int | float) and not isinstance(v, bool)
        if not ok or not math.isfinite(v) or not lo <= v <= hi:
            return f"{v!r} is not {what} in [{lo:g}, {hi:g}]"
        return None
    ranges = {
        "seed": (0, 2**63 - 1),
        "resolution": (16, 4096),
        "images": (2, 72),
        "obstacles": (0, 10_000),
        "motor_faults": (0, 10_000),
    }
    lo, hi = ranges[key]
    if not _is_int(v) or not lo <= v <= hi:
        return f"{v!r} is not a whole number in {lo}..{hi}"
    return None


def _check_grid(where: str, grid: Any, mistakes: list[str]) -> dict[str, list[Any]] | None:
    """The grid's lists, defaults filled in; ``None`` (and mistakes) if it has any."""
    if not isinstance(grid, dict):
        mistakes.append(f"{where} must be a table of lists, e.g. seed = [0, 1]")
        return None
    before = len(mistakes)
    values: dict[str, list[Any]] = {}
    for key, given in grid.items():
        if key not in GRID_KEYS:
            mistakes.append(f"{where}: unknown key {key!r} (known: {', '.join(GRID_KEYS)})")
            continue
        if not isinstance(given, list):
            mistakes.append(f"{where} {key}: must be a list, e.g. {key} = [{_example(key)}]")
            continue
        if not given:
            default = DEFAULTS[key]
            mistakes.append(
                f"{where} {key}: empty list (leave the key out for the default, "
                f"{'per network' if default is None else repr(default)})"
            )
            continue
        clean = [v.strip() if isinstance(v, str) else v for v in given]
        seen: set[Any] = set()
        for v in clean:
            problem = _check_value(key, v)
            if problem is not None:
                mistakes.append(f"{where} {key}: {problem}")
            elif v in seen:
                mistakes.append(f"{where} {key}: {v!r} is listed twice")
            else:
                seen.add(v)
        values[key] = clean
    if len(mistakes) > before:
        return None
    return {k: values.get(k, [DEFAULTS[k]]) for k in GRID_KEYS}


def _example(key: str) -> str:
    default = DEFAULTS[key]
    if default is None:
        return "0.36" if key == "threshold" else '"S"'
    if isinstance(default, bool):
        return "true"
    return f'"{default}"' if isinstance(default, str) else str(default)


def _networks(
    where: str, grid: dict[str, list[Any]], mistakes: list[str]
) -> dict[tuple[str, int], Any]:
    """Every network of the grid, built (cheap: no simulator), by (spec, seed)."""
    from pipemap.sim.network import build_network

    built: dict[tuple[str, int], Any] = {}
    for network in grid["network"]:
        for seed in grid["seed"]:
            try:
                built[(network, seed)] = build_network(network, seed=seed)
            except (SimError, InputError) as exc:
                mistakes.append(f"{where} network {network!r}: {exc}")
                break
    return built


def _driving_problems(values: dict[str, Any], network: Any) -> Iterator[str]:
    """Why a run cannot have its ``obstacles`` or ``motor_faults`` (each as ``key:
    why``): only the autonomous robot drives, and a network has only so many pipes
    long enough for a deposit."""
    placed = values["condition"] != "autonomous"
    for key, meets in (("obstacles", "deposits"), ("motor_faults", "motor cut-outs")):
        count = values[key]
        if count and placed:
            yield (
                f"{key}: {count} with condition {values['condition']!r}: only the autonomous "
                f"robot drives into {meets} (give placed conditions their own [[grid]] table)"
            )
    if values["obstacles"] and not placed:
        from pipemap.sim.obstacles import place_obstacles

        try:
            place_obstacles(network, values["obstacles"], values["seed"])
        except SimError as exc:
            yield (
                f"obstacles: {values['obstacles']} in {values['network']} "
                f"(seed {values['seed']}): {exc}"
            )


def _points(where: str, grid: dict[str, list[Any]], mistakes: list[str]) -> Iterator[RunPoint]:
    networks = _networks(where, grid, mistakes)
    missing: dict[tuple[str, str], list[int]] = {}
    clashes: set[str] = set()
    for combo in itertools.product(*(grid[k] for k in GRID_KEYS)):
        values = dict(zip(GRID_KEYS, combo, strict=True))
        network = networks.get((values["network"], values["seed"]))
        if network is None:
            continue
        if values["start"] is None:
            values["start"] = network.entry
        elif values["start"] not in network.labels:
            missing.setdefault((values["start"], values["network"]), []).append(values["seed"])
            continue
        if values["threshold"] is None:
            values["threshold"] = SCORE_THRESHOLD
        values["threshold"] = float(values["threshold"])
        values["tilt_deg"] = float(values["tilt_deg"])
        values["alike"] = float(values["alike"])
        values["odometry_drift"] = float(values["odometry_drift"])
        problems = set(_driving_problems(values, network))
        if problems:
            clashes |= problems
            continue
        yield RunPoint(**values)
    mistakes.extend(f"{where} {c}" for c in sorted(clashes))
    for (start, network), seeds in missing.items():
        labels = networks[(network, seeds[0])].labels
        mistakes.append(
            f"{where} start {start!r}: no such node in {network} "
            f"(seed {', '.join(map(str, sorted(set(seeds))))}: {', '.join(labels)})"
        )


def parse_spec(text: str, name: str = "SPEC") -> BatchSpec:
    """Validate a SPEC's TOML text; raises :class:`SpecError` naming every mistake."""
    try:
        doc = tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise SpecError(name, [f"not valid TOML: {exc}"]) from None
    mistakes: list[str] = []
    stray = [k for k in doc if k in GRID_KEYS]
    if stray:
        mistakes.append(f"{', '.join(stray)}: grid keys go under the [grid] heading")
    for key in doc:
        if key not in ("grid", "description", *GRID_KEYS):
            mistakes.append(f"unknown top-level key {key!r} (a SPEC has [grid] and description)")
    description = doc.get("description", "")
    if not isinstance(description, str):
        mistakes.append("description must be a string")
        description = ""
    grids = doc.get("grid")
    if grids is None:
        if not stray:
            mistakes.append("no [grid] table (its keys each hold a list of values to run)")
        grids = []
    elif isinstance(grids, dict):
        grids = [grids]
    elif not grids:
        mistakes.append("[[grid]] is empty")
    points: dict[str, RunPoint] = {}
    for k, grid in enumerate(grids):
        where = "[grid]" if len(grids) == 1 else f"[[grid]] #{k + 1}"
        values = _check_grid(where, grid, mistakes)
        if values is None:
            continue
        for point in _points(where, values, mistakes):
            points.setdefault(point.run_id, point)  # grids may overlap: each run once
    if mistakes:
        raise SpecError(name, mistakes)
    return BatchSpec(name, text, description, tuple(points.values()))


def load_spec(path: Path) -> BatchSpec:
    """Read and validate the SPEC file ``path``."""
    if path.is_dir():
        raise InputError(f"SPEC {path}: is a folder, not a TOML file")
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise InputError(f"SPEC {path}: no such file") from None
    except UnicodeDecodeError:
        raise SpecError(str(path), ["not valid TOML: not UTF-8 text"]) from None
    return parse_spec(text, str(path))
