"""Subcommands of `dpcbench`: one module each, each with ``register(subparsers)``."""
