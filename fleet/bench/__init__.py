"""Benchmarks (``parkfleet bench …``): numbers and ratios measured in one run, no pass/fail.

- :mod:`~fleet.bench.sim`: batch simulator robot-steps/s against a plain Python loop.
- :mod:`~fleet.bench.zenoh`: state delivery of N simulated robots through a router.
- :mod:`~fleet.bench.api`: POST /tasks throughput and latency against a live server.
- :mod:`~fleet.bench.fleet`: the fleet through the real service and sim agents, per policy,
  beside navground's planners; its parts: :mod:`~fleet.bench.scenarios` (scenario data,
  builders, the JSON file format, the suites), :mod:`~fleet.bench.metrics` (metrics on
  time-aligned true poses), :mod:`~fleet.bench.peers` (navground ORCA, HRVO, HL, social
  force on the same robots), :mod:`~fleet.bench.plots` (a PNG per run),
  :mod:`~fleet.bench.report` (the README's tables).
"""

__all__: list[str] = []
