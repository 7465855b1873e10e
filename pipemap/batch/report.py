"""``pipemap batch-report DIR``: a batch's results, grouped, as Markdown and PNG.

The runs are grouped by the grid keys that vary in the batch, seeds aside (the seeds
are the repetitions), or by the keys asked for. For each group: how many runs, how
many failed, how many built the true map, and the mean, std, min and max over the
group's runs of each score. Two figures in the manner of the paper's: Figure 7's box
plots of the similarity of same- and different-junction pairs (every pair of every
run of the group), and Table 2's rotation error, of same-junction pairs and of the
revisits each run recognised.
"""

from __future__ import annotations

import json
import math
import statistics
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from pipemap.batch.results import read_result, read_table
from pipemap.batch.spec import GRID_KEYS, RULES
from pipemap.errors import InputError
from pipemap.wholefile import write_whole

__all__ = ["METRICS", "REPORT_FILES", "group_runs", "report_document", "write_report"]

REPORT_FILES = ("report.md", "report.json", "report_similarity.png", "report_rotation.png")

#: The scores summarised per group: column (or ``right``, the fraction of decisions
#: right) and what it is.
METRICS: tuple[tuple[str, str], ...] = (
    ("map_correct", "map correct (1 = the true map)"),
    ("right", "decisions right (fraction of visits)"),
    ("decisions.false_merge", "false merges"),
    ("decisions.false_new", "false new"),
    ("pairs.same.mean", "similarity of same-junction pairs (run mean)"),
    ("pairs.different.mean", "similarity of different-junction pairs (run mean)"),
    ("similarity.known.mean", "best similarity of revisits (run mean)"),
    ("similarity.unknown.mean", "best similarity of first visits (run mean)"),
    ("rotation_error_rad.known.mean", "rotation error of recognised revisits, rad (run mean)"),
    ("rotation_error_rad.known.max", "rotation error of recognised revisits, rad (run max)"),
    ("pairs.rotation_error_rad.mean", "rotation error of same-junction pairs, rad (run mean)"),
    ("latency_ms.mean", "decision latency, ms (run mean)"),
    ("record_wall_s", "recording wall time, s"),
)


def _value(row: Mapping[str, Any], metric: str) -> float | None:
    if metric == "right":
        visits = row.get("visits")
        if not visits:
            return None
        right = row["decisions.correct_known"] + row["decisions.correct_new"]
        return float(right) / float(visits)
    value = row.get(metric)
    if value is None or isinstance(value, str):
        return None
    return float(value)


def stats(values: Sequence[float]) -> dict[str, Any]:
    """Mean, population std, min, max and count, 4 decimals (``None`` when empty)."""
    if not values:
        return {"n": 0, "mean": None, "std": None, "min": None, "max": None}
    return {
        "n": len(values),
        "mean": round(statistics.fmean(values), 4),
        "std": round(statistics.pstdev(values), 4),
        "min": round(min(values), 4),
        "max": round(max(values), 4),
    }


def _default_keys(rows: Sequence[Mapping[str, Any]]) -> tuple[str, ...]:
    return tuple(k for k in GRID_KEYS if k != "seed" and len({json.dumps(r[k]) for r in rows}) > 1)


def group_runs(
    rows: Sequence[Mapping[str, Any]], by: Sequence[str]
) -> list[tuple[tuple[Any, ...], list[Mapping[str, Any]]]]:
    """The rows grouped by the values of ``by``, groups in order of first appearance."""
    groups: dict[tuple[Any, ...], list[Mapping[str, Any]]] = {}
    for row in rows:
        groups.setdefault(tuple(row[k] for k in by), []).append(row)
    return list(groups.items())


def report_document(folder: Path, by: Sequence[str] | None = None) -> dict[str, Any]:
    """The grouped statistics of the batch in ``folder``, as one JSON-ready object."""
    table = read_table(folder)
    rows = table["runs"]
    if not rows:
        raise InputError(f"{folder}: no finished run to report")
    if by is None:
        by = _default_keys(rows)
    for key in by:
        if key not in GRID_KEYS:
            raise InputError(f"--by {key}: not a grid key ({', '.join(GRID_KEYS)})")
    groups = []
    for values, members in group_runs(rows, by):
        ok = [r for r in members if r["status"] == "ok"]
        groups.append(
            {
                "group": dict(zip(by, values, strict=True)),
                "runs": len(members),
                "failed": len(members) - len(ok),
                "map_correct": sum(1 for r in ok if r["map_correct"]),
                "seeds": sorted({r["seed"] for r in members}),
                "metrics": {
                    m: stats([v for r in ok if (v := _value(r, m)) is not None]) for m, _ in METRICS
                },
                "run_ids": [r["run_id"] for r in members],
            }
        )
    rules = sorted({r["rule"] for r in rows}, key=list(RULES).index)
    return {
        "spec": table["spec"],
        "description": table.get("description", ""),
        "pipemap_version": table["pipemap_version"],
        "runs_total": table["runs_total"],
        "runs_finished": table["runs_finished"],
        "runs_failed": table["runs_failed"],
        "by": list(by),
        "rules": {name: list(RULES[name].flags) for name in rules},
        "thresholds": sorted({r["threshold"] for r in rows}),
        "groups": groups,
    }


def _num(value: float | None, digits: int = 3) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def _label(group: Mapping[str, Any]) -> str:
    return " ".join(str(v).lower() if isinstance(v, bool) else str(v) for v in group.values())


def _markdown(doc: Mapping[str, Any]) -> str:
    by = doc["by"]
    head = "| " + " | ".join(by or ["all runs"]) + " |"
    rule = "|" + "---|" * max(1, len(by))

    def cells(group: Mapping[str, Any]) -> str:
        if not by:
            return "| all |"
        return "| " + " | ".join(_label({k: v}) for k, v in group["group"].items()) + " |"

    lines = [
        f"# Batch report: `{doc['spec']}`",
        "",
        *([doc["description"], ""] if doc["description"] else []),
        f"pipemap {doc['pipemap_version']}: {doc['runs_finished']} of {doc['runs_total']} runs "
        f"finished, {doc['runs_failed']} failed. The SPEC is `spec.toml` beside this report "
        f"(run as `{doc['spec']}`): `pipemap batch spec.toml --out DIR` rebuilds the runs, "
        "`pipemap batch-report DIR` this report.",
        "",
        "Decision rules (each run was replayed and scored as `pipemap score` with these flags):",
        "",
    ]
    for name, flags in doc["rules"].items():
        command = f"`{RULES[name].command()}`" + ("" if flags else " (no flags)")
        lines.append(f"- `{name}` ({command}): {RULES[name].description}")
    lines += [
        "",
        f"Grouped by {', '.join(by) if by else 'nothing (one group)'}; each group's numbers "
        "are over its runs (seeds pooled). Statistics: mean ± population std, min, max.",
        "",
        "## Maps and decisions",
        "",
        head[:-1] + "| runs | failed | map correct | decisions right | false merges | false new |",
        rule + "---|---|---|---|---|---|",
    ]
    for g in doc["groups"]:
        m = g["metrics"]
        ok = g["runs"] - g["failed"]
        lines.append(
            cells(g)[:-1] + f"| {g['runs']} | {g['failed']} | {g['map_correct']}/{ok} | "
            f"{_summary(m['right'])} | {_summary(m['decisions.false_merge'])} | "
            f"{_summary(m['decisions.false_new'])} |"
        )
    for metric, description in METRICS[2:]:
        lines += [
            "",
            f"## `{metric}`: {description}",
            "",
            head[:-1] + "| n | mean | std | min | max |",
            rule + "---|---|---|---|---|",
        ]
        for g in doc["groups"]:
            s = g["metrics"][metric]
            lines.append(
                cells(g)[:-1] + f"| {s['n']} | {_num(s['mean'], 4)} | {_num(s['std'], 4)} | "
                f"{_num(s['min'], 4)} | {_num(s['max'], 4)} |"
            )
    lines += [
        "",
        "## Figure 7 style: same against different junctions",
        "",
        "Every pair of visit sweeps of every run of the group (the pairs do not depend on "
        "the decision rule).",
        "",
        "![similarity of same- and different-junction pairs](report_similarity.png)",
        "",
        "## Table 2 style: rotation error",
        "",
        "Same-junction pairs (the paper's estimate between the two sweeps) and the revisits "
        "each run recognised (the rule's own estimate), in radians.",
        "",
        "![rotation error](report_rotation.png)",
        "",
    ]
    return "\n".join(lines)


def _summary(s: Mapping[str, Any]) -> str:
    if not s["n"]:
        return "-"
    return f"{s['mean']:.3f} ± {s['std']:.3f} ({s['min']:.3f}–{s['max']:.3f})"


def _figures(folder: Path, doc: Mapping[str, Any]) -> tuple[Any, Any]:
    from pipemap.batch.plots import DIFFERENT, SAME, Box, box_plot

    similarity, rotation = [], []
    largest = 0.0
    for g in doc["groups"]:
        same: list[float] = []
        different: list[float] = []
        pair_errors: list[float] = []
        known_errors: list[float] = []
        for run_id in g["run_ids"]:
            result = read_result(folder, run_id)
            if result is None or result["status"] != "ok":
                continue
            same += result["pairs"]["same"]
            different += result["pairs"]["different"]
            pair_errors += result["pairs"]["rotation_error_rad"]
            known_errors += result["known_rotation_errors_rad"]
        label = _label(g["group"]) if doc["by"] else "all runs"
        similarity.append((label, [Box(same, SAME, "same"), Box(different, DIFFERENT, "diff")]))
        rotation.append(
            (label, [Box(pair_errors, SAME, "pairs"), Box(known_errors, DIFFERENT, "known")])
        )
        largest = max([largest, *pair_errors, *known_errors])
    thresholds = doc["thresholds"]
    figure7 = box_plot(
        similarity,
        "Similarity of same- and different-junction pairs",
        threshold=thresholds[0] if len(thresholds) == 1 else None,
        legend=[("same junction", SAME), ("different junctions", DIFFERENT)],
    )
    top = max(0.1, math.ceil(largest * 10) / 10)
    table2 = box_plot(
        rotation,
        "Rotation error: same-junction pairs and recognised revisits",
        y_label="error (rad)",
        y_range=(0.0, top),
        legend=[("same-junction pairs", SAME), ("recognised revisits", DIFFERENT)],
    )
    return figure7, table2


def write_report(folder: Path, by: Sequence[str] | None = None) -> list[Path]:
    """Write ``report.md``, ``report.json`` and the two figures into ``folder``."""
    import cv2

    doc = report_document(folder, by)
    figure7, table2 = _figures(folder, doc)
    paths = [folder / name for name in REPORT_FILES]
    write_whole(paths[0], _markdown(doc))
    write_whole(paths[1], json.dumps(doc, indent=2, allow_nan=False) + "\n")
    write_whole(paths[2], cv2.imencode(".png", figure7)[1].tobytes())
    write_whole(paths[3], cv2.imencode(".png", table2)[1].tobytes())
    return paths
