"""Small helpers shared by several benchmarks (beside ``benchmarks.common``)."""

from __future__ import annotations


def falls_with_h(rows: list[dict], key: str, group: tuple[str, ...]) -> dict[tuple, bool]:
    """Whether ``row[key]`` falls at every refinement (h decreasing), per group of ``rows``
    (the values of the keys ``group``, in order of first appearance) holding two h or more;
    rows whose ``key`` is None are left out. ``rows``: dicts with ``"h"`` (m), ``key`` and
    ``group``."""
    series: dict[tuple, list] = {}
    for row in sorted(rows, key=lambda r: -r["h"]):
        if row[key] is not None:
            series.setdefault(tuple(row[g] for g in group), []).append(row[key])
    return {
        g: all(b < a for a, b in zip(v, v[1:], strict=False))
        for g, v in series.items()
        if len(v) > 1
    }


def check_settings(where: str, settings: dict, keys: tuple[str, ...]) -> None:
    """A ValueError naming the keys of ``keys`` missing from ``settings`` and those of
    ``settings`` not among ``keys`` (``where``: the function that checks, e.g.
    ``"hertz.run_point"``)."""
    missing = [key for key in keys if key not in settings]
    unknown = sorted(set(settings) - set(keys))
    if missing or unknown:
        raise ValueError(f"{where}: missing settings {missing}, unknown {unknown}")
