"""dpcbench: the harness that wires methods/, holes/ and metrics/ together (CLI, data, runner, store)."""

__version__ = "0.1.0"
