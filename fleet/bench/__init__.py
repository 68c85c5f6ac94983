"""Benchmarks (``parkfleet bench …``): numbers and ratios measured in one run, no pass/fail.

- :mod:`~fleet.bench.sim`: batch simulator robot-steps/s against a plain Python loop.
- :mod:`~fleet.bench.zenoh`: robots' states at the agents' rate into the real fleet service
  (:mod:`~fleet.bench.state_stream`: a light stand-in for many robots on the wire).
- :mod:`~fleet.bench.api`: POST /tasks throughput and latency against a live server while
  simulated robots stream their state and the planner runs.
- :mod:`~fleet.bench.fleet`: the fleet through the real service and sim agents, per policy,
  beside navground's planners; its parts: :mod:`~fleet.bench.scenarios` (scenario data,
  builders, the JSON file format, the suites), :mod:`~fleet.bench.metrics` (metrics on
  time-aligned true poses), :mod:`~fleet.bench.peers` (navground ORCA, HRVO, HL, social
  force on the same robots), :mod:`~fleet.bench.plots` (a PNG per run),
  :mod:`~fleet.bench.report` (the tables of docs/benchmarks.md).
- :mod:`~fleet.bench.soak`: a long random load; the server's memory, fds and store.
- :mod:`~fleet.bench.plan`: the planner's latency per decision and, offline, its plans'
  quality (:mod:`~fleet.bench.closed_loop`: an offline fleet on the batch simulator that
  calls the planner as the service does).
- :mod:`~fleet.bench.estop`: e-stop latency, request to the tick that zeroed the wheels.
- :mod:`~fleet.bench.on_state`: states per CPU second through the service's hot path.
- :mod:`~fleet.bench.procstat`: what a process costs and holds (``/proc``), for the others.
"""

__all__: list[str] = []
