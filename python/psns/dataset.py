"""PSNS-style datasets from Python: ``psns dataset build`` in-process, and the same build spread
over Dask or Ray workers.

A dataset is split into ``n`` shards by position (sample ``j`` belongs to shard ``j mod n + 1``);
any set of shards, built anywhere and in any order, adds up to the same files, byte for byte, as
one whole build, because every sample's noise is keyed by its own seed, never by the shard or the
worker. The build that finishes the last missing samples writes ``manifest.csv``; a killed shard
is finished by building it again with ``resume=True``. See docs/dataset.md.
"""

from __future__ import annotations

import os
from typing import Any, List, Optional, Tuple

from . import _psns

__all__ = ["build", "build_on_dask", "build_on_ray"]


def build(
    config: "Optional[os.PathLike[str] | str]",
    out: "os.PathLike[str] | str",
    shard: Optional[Tuple[int, int]] = None,
    resume: bool = False,
    jobs: Optional[int] = None,
    dry_run: bool = False,
) -> None:
    """Build a dataset, or shard ``k`` of ``n`` with ``shard=(k, n)``, as ``psns dataset build``.

    ``config``: the dataset description (TOML, docs/dataset.md); ``None`` is the PSNS dataset at
    full size. ``shard=(k, n)`` counts from 1, as the CLI's ``--shard K/N``. ``resume`` keeps the
    samples already present and intact. ``jobs``: samples rendered at once (default: every
    core). The plan (samples, bytes, estimated time) goes to stderr first; ``dry_run`` prints
    it and creates nothing. Raises ``ValueError`` with the CLI's message for bad input.
    """
    _psns.dataset_build(
        None if config is None else os.fspath(config),
        os.fspath(out),
        shard=shard,
        resume=resume,
        jobs=jobs,
        dry_run=dry_run,
    )


def _shard_task(config: Optional[str], out: str, k: int, n: int, jobs: Optional[int]) -> int:
    build(config, out, shard=(k, n), resume=True, jobs=jobs)
    return k


def build_on_dask(
    client: Any,
    config: "Optional[os.PathLike[str] | str]",
    out: "os.PathLike[str] | str",
    shards: int,
    jobs: Optional[int] = 1,
) -> List[int]:
    """Build ``shards`` shards as Dask tasks on ``client`` (a ``dask.distributed.Client``);
    returns the shard numbers built. ``out`` must be a directory every worker can write (a
    shared file system on a cluster). Each task resumes its shard, so a task Dask retries after a
    lost worker keeps what was already written. ``jobs`` per task (default 1: one core per task,
    the scheduler spreads the tasks)."""
    cfg = None if config is None else os.fspath(config)
    futures = [
        client.submit(_shard_task, cfg, os.fspath(out), k, shards, jobs, pure=False)
        for k in range(1, shards + 1)
    ]
    return client.gather(futures)


def build_on_ray(
    config: "Optional[os.PathLike[str] | str]",
    out: "os.PathLike[str] | str",
    shards: int,
    jobs: Optional[int] = 1,
) -> List[int]:
    """Build ``shards`` shards as Ray tasks (``ray.init()`` first); returns the shard numbers
    built. Same contract as :func:`build_on_dask`."""
    import ray  # optional dependency

    task = ray.remote(_shard_task)
    cfg = None if config is None else os.fspath(config)
    return ray.get([task.remote(cfg, os.fspath(out), k, shards, jobs) for k in range(1, shards + 1)])
