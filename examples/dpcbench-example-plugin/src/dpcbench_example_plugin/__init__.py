"""A dpcbench plug-in: `QuadricFill`, registered as ``quadric-fill`` (entry point group
``dpcbench.methods``). See docs/adding-a-method.md in the dpcbench repository."""

from dpcbench_example_plugin.fills import QuadricFill

__all__ = ["QuadricFill"]
