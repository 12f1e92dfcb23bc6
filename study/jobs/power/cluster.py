"""The Dask engine of ``asa power`` (issue 22): a ``LocalCluster`` of worker processes by
default, or an existing Dask scheduler by address (lab machines, dask-jobqueue on SLURM).
Workers each own their pybullet client (one per process, made by the trial); BLAS runs one
thread per worker; results return to the client, which alone writes files."""

from __future__ import annotations

import contextlib
import logging
import re
from collections.abc import Iterator
from dataclasses import dataclass

CONNECT_TIMEOUT_S = 5.0  # [s] an unreachable scheduler is reported after this
_ADDRESS = re.compile(r"^(?:(tcp|tls)://)?(\[[0-9a-fA-F:]+\]|[A-Za-z0-9._-]+):(\d{1,5})$")


@dataclass(frozen=True, slots=True)
class Engine:
    """A connected Dask client and what it is, in words (for the report's settings)."""

    client: object  # distributed.Client
    description: str


def check_address(address: str) -> str:
    """``tcp://host:port`` (or ``tls://``; a bare ``host:port`` means tcp), else ValueError."""
    match = _ADDRESS.match(address.strip())
    if match is None or not 0 < int(match.group(3)) < 65536:
        raise ValueError(
            f"--scheduler: {address!r} is not a Dask scheduler address; expected "
            f"tcp://host:port (e.g. tcp://192.168.1.10:8786)"
        )
    scheme = match.group(1) or "tcp"
    return f"{scheme}://{match.group(2)}:{match.group(3)}"


def _worker_version() -> str:
    import study

    return study.__version__


@contextlib.contextmanager
def dask_engine(scheduler: str | None, workers: int) -> Iterator[Engine]:
    """A Dask client for the duration of the ``with`` block.

    Parameters
    ----------
    scheduler : str, optional
        Address of a running scheduler (``dask scheduler``); None starts a
        ``LocalCluster(n_workers=workers, threads_per_worker=1, processes=True)``.
    workers : int
        Worker processes of the local cluster (ignored with ``scheduler``).

    Raises
    ------
    ValueError
        A malformed address, a scheduler not reachable within :data:`CONNECT_TIMEOUT_S`,
        or workers running another version of asa-study.
    """
    from study._blas import limit_blas_threads

    limit_blas_threads()  # in the environment: local worker processes inherit it
    from distributed import Client, LocalCluster

    cluster = None
    if scheduler is None:
        cluster = LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True,
            # the scheduler's HTTP server on a free local port, not 8787: two analyses
            # (or a lab's own cluster) on one machine do not collide
            dashboard_address="127.0.0.1:0", silence_logs=logging.ERROR,
        )  # fmt: skip
        client = Client(cluster)
        description = f"LocalCluster, {workers} worker process{'es' if workers > 1 else ''}"
    else:
        address = check_address(scheduler)
        try:
            client = Client(address, timeout=f"{CONNECT_TIMEOUT_S:g}s")
        except (OSError, TimeoutError) as error:
            raise ValueError(
                f"--scheduler: cannot reach a Dask scheduler at {address} within "
                f"{CONNECT_TIMEOUT_S:g} s ({type(error).__name__}); start one with "
                f"'dask scheduler' (README, 'Power analysis on a cluster')"
            ) from None
        count = len(client.scheduler_info().get("workers", {}))
        description = f"{address} ({count} worker{'s' if count != 1 else ''} at the start)"
    try:
        _check_versions(client)
        yield Engine(client, description)
    finally:
        client.close()
        if cluster is not None:
            cluster.close()


def _check_versions(client) -> None:
    """Workers must run this version of asa-study (the bank's rows depend on it)."""
    import study

    versions = client.run(_worker_version)
    other = {w: v for w, v in versions.items() if v != study.__version__}
    if other:
        worker, version = next(iter(other.items()))
        raise ValueError(
            f"--scheduler: worker {worker} runs asa-study {version}, this client "
            f"{study.__version__}; install the same version on every worker"
        )
