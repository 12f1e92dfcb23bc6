"""`asa` limits BLAS to one thread, also for numpy loaded later and in worker processes."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]  # the checkout under test, not an installed copy

PROBE = """
import concurrent.futures as cf, multiprocessing
from study._blas import limit_blas_threads

def threads():
    import numpy, scipy.linalg  # noqa: F401  (loads the BLAS libraries)
    from threadpoolctl import threadpool_info
    return sorted({i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"})

if __name__ == "__main__":
    limit_blas_threads()  # before numpy is loaded, as `asa` calls it
    ctx = multiprocessing.get_context("spawn")
    with cf.ProcessPoolExecutor(1, mp_context=ctx, initializer=limit_blas_threads) as pool:
        print(threads(), pool.submit(threads).result())
"""


def test_blas_runs_one_thread_here_and_in_spawned_workers(tmp_path):
    script = tmp_path / "probe.py"
    script.write_text(PROBE)
    env = {k: v for k, v in os.environ.items() if not k.endswith("_NUM_THREADS")}
    env.pop("ASA_BLAS_THREADS", None)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    out = subprocess.run(
        [sys.executable, str(script)], env=env, capture_output=True, text=True, timeout=120
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.split() == ["[1]", "[1]"]
