"""One BLAS thread per process: :func:`limit_blas_threads`, for the ``asa`` command and
every worker pool."""

from __future__ import annotations

import os
import sys


def limit_blas_threads() -> None:
    """One BLAS thread per process unless ``ASA_BLAS_THREADS`` says otherwise.

    BLAS reads its thread count when it is loaded, so the limit goes into the
    environment (``OPENBLAS_NUM_THREADS``, ``MKL_NUM_THREADS``, ``OMP_NUM_THREADS``):
    it then holds for numpy loaded later in this process and in every worker process
    it starts. ``threadpoolctl`` only reaches libraries already loaded, so it is used
    as well when numpy is. Also a worker pool's initializer.

    Raises
    ------
    ValueError
        ``ASA_BLAS_THREADS`` is not a positive integer.
    """
    threads = os.environ.get("ASA_BLAS_THREADS", "1")
    if not threads.isdigit() or int(threads) < 1:
        raise ValueError(
            f"environment variable ASA_BLAS_THREADS: must be a positive integer, got {threads!r}"
        )
    for name in ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS"):
        os.environ[name] = threads
    if "numpy" in sys.modules:
        from threadpoolctl import threadpool_limits

        threadpool_limits(int(threads), user_api="blas")
