"""Work on a Dask distributed cluster: a local one by default, or any running scheduler.

Why Dask (``dask.distributed``) and not Ray: the work here is coarse tasks of plain Python and
numpy (a dataset shard, a sweep point) with no shared state between them, which Dask's futures
and its ``concurrent.futures`` executor fit with no extra concepts; it is pure Python from PyPI
(Ray ships large native wheels and its own object store and dashboard server); a ``LocalCluster``
starts in ~2 s on a laptop and ``dask scheduler`` / ``dask worker`` on other machines need nothing
but the same environment; and ``performance_report`` writes the engine's own HTML report of a run
(task stream, worker profiles) without a dashboard left running.

    with cluster_client(workers=2) as client:            # a local cluster of 2 worker processes
        generate(scene, n, seed, out, executor=client.get_executor())
    with cluster_client("tcp://10.0.0.5:8786") as client:  # a running scheduler
        ...

Dask is an optional extra (``pip install "tactile-learn[cluster]"``): imported only here, inside
the functions that need it.
"""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import AbstractContextManager, contextmanager, nullcontext
from pathlib import Path
from typing import Any

from synth.errors import ConfigError

__all__ = ["cluster_client", "performance_report"]


def _distributed() -> Any:
    try:
        import distributed
    except ImportError:
        raise ConfigError("the Dask cluster engine is not installed: pip install 'tactile-learn[cluster]'") from None
    return distributed


@contextmanager
def cluster_client(
    scheduler: str | None = None, *, workers: int = 2, threads_per_worker: int = 1, timeout_s: float = 20.0
) -> Iterator[Any]:
    """A ``distributed.Client``: connected to ``scheduler`` (an address such as ``tcp://host:8786``,
    given up after ``timeout_s``), or to a fresh local cluster of ``workers`` processes that closes
    on exit.

    Local workers run one thread each (the simulator and training are single-threaded numpy/torch
    work; one process per core scales without oversubscription) and their dashboard binds to a free
    port on localhost only."""
    distributed = _distributed()
    if scheduler:
        try:
            client = distributed.Client(scheduler, timeout=f"{timeout_s}s")
        except OSError as exc:
            raise ConfigError(f"--scheduler: cannot reach {scheduler} ({exc})") from None
        try:
            yield client
        finally:
            client.close()
        return
    if workers < 1:
        raise ConfigError(f"workers: expected a positive integer, got {workers}")
    cluster = distributed.LocalCluster(
        n_workers=workers,
        threads_per_worker=threads_per_worker,
        processes=True,
        dashboard_address="127.0.0.1:0",
        host="127.0.0.1",
    )
    client = distributed.Client(cluster)
    try:
        yield client
    finally:
        client.close()
        cluster.close()


def performance_report(path: str | Path | None) -> AbstractContextManager[Any]:
    """Dask's own HTML report of everything run inside the block (task stream, worker profiles),
    written to ``path``; a no-op without a path."""
    if path is None:
        return nullcontext()
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    report: AbstractContextManager[Any] = _distributed().performance_report(filename=str(path))
    return report
