"""``asa bench``: the single benchmark entry point of the project.

Every performance budget of DESIGN.md is measured here, never asserted in a
test. A group is a module ``study.bench.<group>`` with a function
``run(quick: bool) -> dict`` returning flat JSON-ready figures; the results of
all groups are merged into one JSON object. To add a group, write the module and
add it to ``GROUPS``.
"""

from __future__ import annotations

import importlib
import os
import platform
import time
from collections.abc import Callable

# group name -> module implementing run(quick) -> dict
GROUPS: dict[str, str] = {
    "sim": "study.bench.sim",
    "autonomy": "study.bench.autonomy",
    "report": "study.bench.report",
    "ui": "study.bench.ui",
    "trial": "study.bench.trial",
    "synth": "study.bench.synth",
}


def run_benchmarks(
    only: list[str] | None = None,
    *,
    quick: bool = False,
    progress: Callable[[str], None] | None = None,
) -> dict:
    """Run the named benchmark groups (all when ``only`` is empty) and merge their figures.

    Parameters
    ----------
    only : names from :data:`GROUPS`; unknown names raise ``ValueError``.
    quick : fewer repetitions, for smoke tests; figures are noisier.
    progress : called with each group's name before it runs.
    """
    names = list(only) if only else list(GROUPS)
    unknown = [n for n in names if n not in GROUPS]
    if unknown:
        raise ValueError(
            f"asa bench: --only {unknown[0]!r} is not a benchmark group; "
            f"allowed: {', '.join(GROUPS)}"
        )
    result: dict = {
        "machine": {
            "python": platform.python_version(),
            "cpu_count": os.cpu_count(),
            "platform": platform.platform(),
        },
        "quick": quick,
    }
    for name in names:
        if progress is not None:
            progress(name)
        start = time.perf_counter()
        figures = importlib.import_module(GROUPS[name]).run(quick=quick)
        figures[f"{name}_bench_wall_s"] = round(time.perf_counter() - start, 3)
        result.update(figures)
    return result
