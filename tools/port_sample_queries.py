"""Port the Tight-Inclusion "Sample-Queries" CCD benchmark to test data (issue 44).

Source: the public data set of Wang, Ferguson, Schneider, Jiang, Attene & Panozzo, "A Large Scale
Benchmark and an Inclusion-Based Algorithm for Continuous Collision Detection", ACM Transactions
on Graphics 40(5), 2021; repository https://github.com/Continuous-Collision-Detection/Sample-Queries
at commit ``a744562c7a842e9eee033fcea290e75a4a8e7b4e`` (2023-10-03), MIT License, Copyright (c)
2020 Bolun Wang, Zachary Ferguson, Teseo Schneider, Xin Jiang, Marco Attene, and Daniele Panozzo.
The license text is copied into the header of the written JSON.

Format of the source (its README): each CSV ``SCENE/{edge-edge,vertex-face}/data_*.csv`` holds 8
rows per query, vertex positions at t = 0 then t = 1 (edge-edge: ea0, ea1, eb0, eb1; vertex-face:
v, f0, f1, f2), 7 integer columns: x, y, z as numerator/denominator pairs and the ground truth
(1: the primitives touch for some t in [0, 1] along the linear trajectories of the exact
rational positions, 0: they do not).

What is kept. bfemp's CCD (:mod:`geometry.ccd`) takes float64 positions ``x`` and displacements
``dx`` and follows ``x + t dx`` exactly (its certificates are for exact arithmetic on the float
inputs). The ground truth therefore carries over to a query only where every position at t = 0
and t = 1 is a float64 exactly (``Fraction(float(q)) == q``) *and* every displacement ``x1 - x0``
is one too (else ``x0 + fl(x1 - x0)`` misses ``x1`` and the float trajectory is not the one the
ground truth is about). Of those, every ground-truth positive is kept (they test for false
negatives) and a seeded sample of at most ``--negatives-per-group`` negatives per (scene, kind)
(a conservative CCD may report an impact for them; they measure the cost). The counts of read,
absent, dropped and kept queries per scene and kind are written with the data.

Some files of the repository are stored as large objects that the local mirror does not hold
(the chain, cow-heads, golf-ball and mat-twist scenes at the commit above); they are listed in the
output as absent. Run from the repository root::

    python tools/port_sample_queries.py [--mirror PATH] [--out PATH]
"""

from __future__ import annotations

import argparse
import json
import subprocess
from collections import Counter
from fractions import Fraction
from pathlib import Path

import numpy as np

COMMIT = "a744562c7a842e9eee033fcea290e75a4a8e7b4e"
MIRROR = "/work/.mirror/Continuous-Collision-Detection+Sample-Queries/repo"
OUT = Path(__file__).resolve().parents[1] / "tests/geometry/data/sample_queries_ccd.json"
KINDS = {"vertex-face": "point_triangle", "edge-edge": "edge_edge"}
SEED = 44
COUNT_KEYS = [
    f"{what}_{sign}{why}"
    for sign in ("positive", "negative")
    for what, why in (
        ("read", ""),
        ("dropped", "_position_not_float"),
        ("dropped", "_displacement_not_float"),
        ("exact", ""),
        ("kept", ""),
    )
]


def _git(mirror: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run(["git", "-C", mirror, *args], capture_output=True, text=True)


def read_queries(text: str, path: str) -> list[tuple[list[list[Fraction]], bool]]:
    """Queries of one CSV: per query the 8 rational vertex rows (x, y, z) and the ground truth."""
    rows = [[int(v) for v in line.split(",")] for line in text.split()]
    if len(rows) % 8 or any(len(r) != 7 for r in rows):
        raise ValueError(f"{path}: expected 8 rows of 7 integers per query")
    out = []
    for q in range(len(rows) // 8):
        block = rows[8 * q : 8 * q + 8]
        truth = {r[6] for r in block}
        if len(truth) != 1 or not truth <= {0, 1}:
            raise ValueError(f"{path}: query {q} has ground-truth column {truth}")
        xyz = [[Fraction(r[2 * j], r[2 * j + 1]) for j in range(3)] for r in block]
        out.append((xyz, truth.pop() == 1))
    return out


def float_exact(xyz: list[list[Fraction]]) -> tuple[bool, bool]:
    """(every position is a float64, every displacement t1 - t0 is one too)."""
    positions = all(Fraction(float(v)) == v for row in xyz for v in row)
    if not positions:
        return False, False
    disp = all(
        Fraction(float(xyz[i + 4][j]) - float(xyz[i][j])) == xyz[i + 4][j] - xyz[i][j]
        for i in range(4)
        for j in range(3)
    )
    return True, disp


def port(mirror: str, negatives_per_group: int) -> dict:
    listing = _git(mirror, "ls-tree", "-r", "--name-only", COMMIT)
    if listing.returncode:
        raise SystemExit(f"cannot list commit {COMMIT} in {mirror}: {listing.stderr.strip()}")
    csvs = sorted(p for p in listing.stdout.split() if p.endswith(".csv"))
    rng = np.random.default_rng(SEED)
    absent, counts, groups = [], {}, {}
    for path in csvs:
        scene, kind_dir, _ = path.split("/")
        kind = KINDS[kind_dir]
        shown = _git(mirror, "show", f"{COMMIT}:{path}")
        if shown.returncode:
            absent.append(path)
            continue
        c = counts.setdefault(f"{scene}/{kind}", Counter(dict.fromkeys(COUNT_KEYS, 0)))
        pos, neg = groups.setdefault(f"{scene}/{kind}", ([], []))
        for index, (xyz, truth) in enumerate(read_queries(shown.stdout, path)):
            sign = "positive" if truth else "negative"
            c[f"read_{sign}"] += 1
            positions, disp = float_exact(xyz)
            if not positions:
                c[f"dropped_{sign}_position_not_float"] += 1
                continue
            if not disp:
                c[f"dropped_{sign}_displacement_not_float"] += 1
                continue
            c[f"exact_{sign}"] += 1
            (pos if truth else neg).append(
                {
                    "scene": scene,
                    "kind": kind,
                    "file": path,
                    "index": index,
                    "collision": truth,
                    "x0": [[float(v) for v in row] for row in xyz[:4]],
                    "x1": [[float(v) for v in row] for row in xyz[4:]],
                }
            )
    # Per (scene, kind): every positive and a seeded sample of the negatives.
    out = []
    for group in sorted(groups):
        pos, neg = groups[group]
        if len(neg) > negatives_per_group:
            pick = np.sort(rng.choice(len(neg), negatives_per_group, replace=False))
            neg = [neg[i] for i in pick]
        counts[group]["kept_positive"] = len(pos)
        counts[group]["kept_negative"] = len(neg)
        out.extend(pos + neg)
    totals = Counter()
    for c in counts.values():
        totals.update(c)
    return {
        "source": (
            "Sample-Queries of Wang, Ferguson, Schneider, Jiang, Attene & Panozzo, 'A Large Scale "
            "Benchmark and an Inclusion-Based Algorithm for Continuous Collision Detection', ACM "
            "TOG 40(5) 2021 (https://github.com/Continuous-Collision-Detection/Sample-Queries, "
            f"commit {COMMIT}), MIT License (below). Converted by tools/port_sample_queries.py: "
            "rational coordinates written as the float64 they equal exactly; only queries whose "
            "positions and displacements are all exact float64 (so the exact ground truth holds "
            "for the float trajectory x0 + t (x1 - x0)); every positive kept, a seeded sample "
            f"(seed {SEED}, at most {negatives_per_group} per scene and kind) of the negatives."
        ),
        "license": _git(mirror, "show", f"{COMMIT}:LICENSE").stdout,
        "fields": (
            "scene; kind (point_triangle: rows p, t0, t1, t2 = the source's vertex-face v, f0, "
            "f1, f2; edge_edge: rows ea0, ea1, eb0, eb1); file and index: the source CSV and the "
            "query's position in it (0-based, 8 rows each); collision: the source's ground truth "
            "(touch for some t in [0, 1]); x0, x1 (4, 3): positions at t = 0 and t = 1 (m). "
            "absent_files: source files the mirror used for the port did not hold (stored as "
            "large objects), not ported; counts per scene/kind and totals: queries read, dropped "
            "(a position or a displacement not a float64), exact, kept"
        ),
        "absent_files": absent,
        "counts": {k: {n: v[n] for n in COUNT_KEYS} for k, v in sorted(counts.items())},
        "totals": {n: totals[n] for n in COUNT_KEYS},
        "queries": out,
    }


def write(data: dict, path: Path) -> None:
    """JSON with one query per line (floats as Python's shortest round-trip repr)."""
    head = {k: v for k, v in data.items() if k != "queries"}
    text = json.dumps(head, indent=1)[:-2]
    lines = [json.dumps(q, separators=(",", ":")) for q in data["queries"]]
    text += ',\n "queries": [\n  ' + ",\n  ".join(lines) + "\n ]\n}\n"
    path.write_text(text)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--mirror", default=MIRROR, help="git directory of Sample-Queries")
    ap.add_argument("--out", type=Path, default=OUT)
    ap.add_argument("--negatives-per-group", type=int, default=64)
    args = ap.parse_args()
    data = port(args.mirror, args.negatives_per_group)
    write(data, args.out)
    print(json.dumps(data["totals"], indent=1))
    print(f"{len(data['queries'])} queries, {args.out.stat().st_size} bytes -> {args.out}")


if __name__ == "__main__":
    main()
