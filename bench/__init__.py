"""dpcbench: the harness that wires methods/, holes/ and metrics/ together (CLI, data, runner, store)."""

from importlib import metadata as _metadata

try:  # the one version: pyproject.toml's, as the installed distribution (wheel or editable) records it
    __version__ = _metadata.version("dpcbench")
except _metadata.PackageNotFoundError:  # a source tree imported without installing
    __version__ = "0+unknown"
