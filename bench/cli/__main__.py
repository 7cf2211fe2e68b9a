"""`python -m dpcbench.bench.cli ...`: the command line, as the `dpcbench` script runs it."""

import sys

from dpcbench.bench.cli import main

sys.exit(main())
