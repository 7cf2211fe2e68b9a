"""The lazy name -> ``"module:Attr"`` registry and `import_entry`, re-exported from `metrics.lazy`
(the lowest layer, so that the metrics registry shares it): `holes.registry.GENERATORS`,
`methods.registry.METHODS` and the harness (`bench.execution.worker` loads run specs' ``entry`` strings)
import them from here or there alike."""

from __future__ import annotations

from dpcbench.metrics.lazy import EntryTypeError, LazyRegistry, ObjectRegistry, import_entry, is_import_path

__all__ = ["EntryTypeError", "LazyRegistry", "ObjectRegistry", "import_entry", "is_import_path"]
