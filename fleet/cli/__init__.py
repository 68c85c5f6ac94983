"""The ``parkfleet`` command line: the composition root (it alone may import every package).

One module per command, each exposing ``register(commands, bench)``; :mod:`fleet.cli.main`
builds the parser from them. ``python -m fleet.cli`` runs it without the console script.
"""

from fleet.cli.main import main

__all__ = ["main"]
