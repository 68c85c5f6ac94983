"""parkfleet's fleet package: the layers below, each a subpackage (see docs/architecture.md).

=================  =============================================================  ==========
subpackage         holds                                                          pure?
=================  =============================================================  ==========
``fleet.core``     types, params, control laws, the control step, simulators,     yes
                   wire messages and keys, tasks, goals, assignment, planning
``fleet.paper``    the paper's scenarios, reproduction, plots                     no (files)
``fleet.io``       settings, the Zenoh session builder, ACL, payload decoder,     no
                   child processes
``fleet.service``  the fleet service shell, task store, bus (memory + Zenoh)      no
``fleet.bench``    every benchmark, one module each                               no
``fleet.cli``      the ``parkfleet`` command line (composition root)              no
=================  =============================================================  ==========

Import rules (``.importlinter``, checked by ``make test``): each layer imports only the
layers below it; ``fleet.core`` imports no sockets, threads, clocks, files or logging; only
``fleet.cli`` may import ``api``, ``robot_agent`` or ``sim_agent``.
"""
