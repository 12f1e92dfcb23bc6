"""``asa bench``: the single benchmark entry point of the project.

Every performance budget of DESIGN.md is measured here, never asserted in a test
(:mod:`study.bench.budgets` compares the figures with them). A group is a module
``study.bench.<group>`` with a function ``run(quick: bool) -> dict`` returning flat
JSON-ready figures (a group may take further keyword options, passed by
:func:`measure`'s ``options``); the results of all groups are merged into one JSON
object. To add a group, write the module and add it to ``GROUPS``.
"""

from __future__ import annotations

import importlib
import os
import platform
import time
from collections.abc import Callable, Mapping
from typing import Any

from study.bench.budgets import check_budgets

# group name -> module implementing run(quick) -> dict
GROUPS: dict[str, str] = {
    "sim": "study.bench.sim",
    "autonomy": "study.bench.autonomy",
    "report": "study.bench.report",
    "ui": "study.bench.ui",
    "trial": "study.bench.trial",
    "synth": "study.bench.synth",
    "recognition": "study.bench.recognition",
    "scenes": "study.bench.scenes",
    "map_semantics": "study.bench.map_semantics",
    "storage": "study.bench.storage",
    "power": "study.bench.power",
    "calibrate": "study.bench.calibrate",
    "push": "study.bench.push",
    "lsl": "study.bench.lsl",
    "web": "study.bench.web",
}


def measure(
    only: list[str] | None = None,
    *,
    quick: bool = False,
    progress: Callable[[str], None] | None = None,
    options: Mapping[str, Mapping[str, Any]] | None = None,
) -> dict[str, dict]:
    """Run the named benchmark groups (all when ``only`` is empty): ``{group: figures}``.

    Parameters
    ----------
    only : names from :data:`GROUPS`; unknown names raise ``ValueError``.
    quick : fewer repetitions, for smoke tests; figures are noisier.
    progress : called with each group's name before it runs.
    options : group -> keyword options of its ``run`` (e.g. ``{"recognition":
        {"generated": (20, 21)}}``); a group that does not run may not have any.
    """
    names = list(only) if only else list(GROUPS)
    unknown = [n for n in names if n not in GROUPS]
    if unknown:
        raise ValueError(
            f"only: {unknown[0]!r} is not a benchmark group; allowed: {', '.join(GROUPS)}"
        )
    stray = [g for g in options or {} if g not in names]
    if stray:
        raise ValueError(f"options: group {stray[0]!r} does not run ({', '.join(names)} do)")
    per_group: dict[str, dict] = {}
    for name in names:
        if progress is not None:
            progress(name)
        start = time.perf_counter()
        extra = dict((options or {}).get(name, {}))
        figures = importlib.import_module(GROUPS[name]).run(quick=quick, **extra)
        figures[f"{name}_bench_wall_s"] = round(time.perf_counter() - start, 3)
        per_group[name] = figures
    return per_group


def merge(per_group: dict[str, dict], *, quick: bool) -> dict:
    """One JSON-ready object: ``machine``, ``quick``, every group's figures and
    ``budgets`` (:func:`study.bench.budgets.check_budgets`)."""
    result: dict = {
        "machine": {
            "python": platform.python_version(),
            "cpu_count": os.cpu_count(),
            "platform": platform.platform(),
        },
        "quick": quick,
    }
    for figures in per_group.values():
        result.update(figures)
    result["budgets"] = check_budgets(result, list(per_group))
    return result


def run_benchmarks(
    only: list[str] | None = None,
    *,
    quick: bool = False,
    progress: Callable[[str], None] | None = None,
) -> dict:
    """:func:`measure` the groups and :func:`merge` their figures into one object."""
    return merge(measure(only, quick=quick, progress=progress), quick=quick)
