"""Benchmarks (``parkfleet bench …``): numbers and ratios measured in one run, no pass/fail.

- :mod:`~fleet.bench.sim`: batch simulator robot-steps/s against a plain Python loop.
- :mod:`~fleet.bench.zenoh`: state delivery of N simulated robots through a router.
- :mod:`~fleet.bench.api`: POST /tasks throughput and latency against a live server.
- :mod:`~fleet.bench.fleet`: the fleet through the real service and sim agents, per policy.
"""

__all__: list[str] = []
