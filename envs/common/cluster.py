"""Starting or joining Ray for the project's parallel jobs (the calibration matrix, the swarm's workers)."""

from __future__ import annotations

from typing import Any


def init_ray(address: str | None = None, **kwargs: Any) -> None:
    """``ray.init`` for a job of ours: join the cluster at ``address``, or start a local instance whose workers run
    at the driver's priority. Ray lowers its workers' priority (niceness 15) by default, so on a machine shared
    with other work (a test suite, another benchmark) a local job's tasks got a small share of the CPU while the
    driver waited on them; the measured wall time then said more about the neighbours than about the job."""
    import ray

    local = {} if address else {"_system_config": {"worker_niceness": 0}}
    ray.init(address=address, include_dashboard=False, log_to_driver=False, configure_logging=False, **local, **kwargs)
