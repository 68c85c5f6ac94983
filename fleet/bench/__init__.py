"""Benchmarks (``parkfleet bench …``): numbers and ratios measured in one run, no pass/fail.

- :mod:`~fleet.bench.sim`: batch simulator robot-steps/s against a plain Python loop.
- :mod:`~fleet.bench.zenoh`: robots' states at the agents' rate into the real fleet service
  (:mod:`~fleet.bench.state_stream`: a light stand-in for many robots on the wire).
- :mod:`~fleet.bench.api`: POST /tasks throughput and latency against a live server while
  simulated robots stream their state and the planner runs.
- :mod:`~fleet.bench.fleet`: the fleet through the real service and sim agents, per policy.
- :mod:`~fleet.bench.soak`: a long random load; the server's memory, fds and store.
- :mod:`~fleet.bench.procstat`: what a process costs and holds (``/proc``), for the others.
"""

__all__: list[str] = []
