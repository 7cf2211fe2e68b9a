"""`python -m dpcbench.bench.cli ...`: the command line, as the `dpcbench` script runs it."""

import sys

from dpcbench.bench.cli import main

if __name__ == "__main__":  # not on import (a walk over every module imports this one too)
    sys.exit(main())
