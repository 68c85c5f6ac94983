"""``python -m fleet.cli``: the ``parkfleet`` command without the console script."""

import sys

from fleet.cli.main import main

sys.exit(main())
