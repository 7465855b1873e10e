"""``pipemap match`` and ``pipemap map``: the localizer on image-set folders.

Each command loads (validating every input before any work), calls the pure
localizer and prints; nothing here decides anything the localizer does not.
"""

from __future__ import annotations

import argparse
import json
import sys
from typing import Any, TextIO

from pipemap import api
from pipemap.cli.localizer_options import (
    fast_config,
    hypotheses,
    illumination_setting,
    odometry_check,
    port_check,
    rule_config,
    two_view_settings,
)
from pipemap.localizer import LocalizerConfig, SetMatch, dumps_document

__all__ = ["match_document", "run_map", "run_match"]


def match_document(
    names: list[str], matches: dict[tuple[int, int], SetMatch], threshold: float
) -> dict[str, Any]:
    """The JSON document of ``pipemap match``: every pair, in argument order."""
    return {
        "threshold": threshold,
        "pairs": [
            {
                "a": names[i],
                "b": names[j],
                "similarity": round(m.similarity, 6),
                "image_shift": m.image_shift,
                "pixel_shift": round(m.pixel_shift, 6),
                "rotation_rad": round(m.rotation_rad, 6),
                "rotation_pinhole_rad": round(m.rotation_pinhole_rad, 6),
                "same": m.similarity >= threshold,
            }
            for (i, j), m in sorted(matches.items())
        ],
    }


def run_match(args: argparse.Namespace, out: TextIO, err: TextIO = sys.stderr) -> int:
    """Load the folders, match every pair, print a table or JSON."""
    matches = api.match_image_sets(
        args.dirs,
        fast_config(args),
        args.fov_deg,
        args.keep_top,
        every_offset=args.every_offset,
        reference=args.reference,
        lamp=illumination_setting(args),
    )
    doc = match_document(list(args.dirs), matches, args.threshold)
    if args.json:
        out.write(json.dumps(doc, indent=2) + "\n")
        return 0
    width = max([len(d) for d in args.dirs] + [1])
    out.write(
        f"{'a':<{width}}  {'b':<{width}}  similarity  image_shift  pixel_shift"
        "  rotation_rad  same\n"
    )
    for pair in doc["pairs"]:
        out.write(
            f"{pair['a']:<{width}}  {pair['b']:<{width}}  {pair['similarity']:10.3f}"
            f"  {pair['image_shift']:11d}  {pair['pixel_shift']:11.1f}"
            f"  {pair['rotation_rad']:12.3f}  {'yes' if pair['same'] else 'no'}\n"
        )
    pairs = len(doc["pairs"])
    out.write(f"threshold {args.threshold}; {pairs} {'pair' if pairs == 1 else 'pairs'}\n")
    return 0


def _rotation(visit: dict[str, Any]) -> str:
    """A known visit's turn from its heading to that of the junction's stored sweep,
    as the decision reports it (two-view when there is a fit, else the paper's)."""
    if not visit["known"]:
        return "-"
    two_view = visit["rotation_two_view_rad"]
    rotation = two_view if two_view is not None else visit["rotation_rad"]
    return "-" if rotation is None else f"{rotation:+.4f}"


def _end(edge: dict[str, Any], end: str) -> str:
    """An edge's end as ``node`` or ``node:port``."""
    port = edge[f"{end}_port"]
    return str(edge[end]) if port is None else f"{edge[end]}:{port}"


def run_map(args: argparse.Namespace, out: TextIO, err: TextIO = sys.stderr) -> int:
    """Load the folders as a visit sequence, localize each, print the map."""
    two_view, verify = two_view_settings(args)
    config = LocalizerConfig(
        threshold=args.threshold,
        fast=fast_config(args),
        distinct_consecutive=not args.allow_repeat,
        two_view=two_view,
        verify=verify,
        port_check=port_check(args),
        odometry_check=odometry_check(args),
        hypotheses=hypotheses(args),
        lamp=illumination_setting(args),
    )
    doc = api.map_image_sets(args.dirs, rule_config(args, config), args.fov_deg, args.keep_top)
    if args.json:
        out.write(dumps_document(doc))
        return 0
    width = max([len(d) for d in args.dirs] + [3])
    out.write(f"{'set':<{width}}  node  known  similarity  margin  rotation\n")
    for v in doc["visits"]:
        margin = "-" if v["margin"] is None else f"{v['margin']:.3f}"
        similarity = "-" if v["similarity"] is None else f"{v['similarity']:.3f}"
        out.write(
            f"{v['set']:<{width}}  {v['node']:4d}  {'yes' if v['known'] else 'no ':>5}"
            f"  {similarity:>10}  {margin:>6}  {_rotation(v):>8}\n"
        )
    edges = ", ".join(f"{_end(e, 'u')}-{_end(e, 'v')} ({e['label']})" for e in doc["edges"])
    out.write(f"{len(doc['nodes'])} nodes; edges: {edges or 'none'}\n")
    return 0
