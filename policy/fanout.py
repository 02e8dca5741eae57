"""Fan work out: over local processes by default, over a ray cluster when an address is given.

Why both: one workstation runs the small Table I in minutes with a process pool; the full
protocol (20k-60k episodes per row, 50 epochs, 10 folds) wants many machines, and ray is the
well-kept way to get them without changing the code that describes the work.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from typing import Any


def fan_out(fn: Callable[..., Any], tasks: Sequence[tuple], workers: int | None = None,
            ray_address: str | None = None) -> list[Any]:
    """[fn(*t) for t in tasks], in parallel; results in task order. fn must be importable."""
    if ray_address:
        try:
            import ray
        except ImportError as e:
            raise RuntimeError("--ray-address needs ray: pip install 'uavsearch[ray]'") from e
        ray.init(address=ray_address, ignore_reinit_error=True)
        remote = ray.remote(fn)
        return ray.get([remote.remote(*t) for t in tasks])
    workers = workers or min(len(tasks), os.cpu_count() or 1)
    if workers <= 1 or len(tasks) <= 1:
        return [fn(*t) for t in tasks]
    with ProcessPoolExecutor(max_workers=workers) as pool:
        return list(pool.map(_call, [(fn, t) for t in tasks]))


def _call(job: tuple[Callable[..., Any], tuple]) -> Any:
    fn, args = job
    return fn(*args)
