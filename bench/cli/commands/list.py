"""`dpcbench list`: the sequences, hole generators, methods and metrics this install knows (built-ins
and the plug-ins of installed distributions' entry points), each with whether it can be used here
and, when not, why: a missing optional dependency, a plug-in whose module fails to import, or a
plug-in refused because its name is taken."""

from __future__ import annotations

import json


def register(subparsers) -> None:
    parser = subparsers.add_parser("list", help="list sequences, hole generators, methods and metrics",
                                   description=__doc__)
    parser.add_argument("--data-dir", default=None,
                        help="folder holding the paper's sequences (default: $DPCBENCH_DATA_DIR)")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    parser.set_defaults(func=run)


def sequences(data_dir) -> list[dict]:
    from dpcbench.bench.data.datasets import describe_datasets

    rows = describe_datasets(data_dir)
    for row in rows:
        if row.get("params"):
            row["description"] += "; params: " + ", ".join(f"{k}={v!r}" for k, v in row["params"].items())
        row.pop("params", None)
    return rows


def _origin(registry, name: str) -> str:
    """Where an entry comes from: "" for a built-in, "plug-in from DIST" for an entry point."""
    return f"plug-in from {registry.plugins[name]}" if name in registry.plugins else ""


def _registry_rows(registry, describe) -> list[dict]:
    """One row per entry of a `metrics.lazy.LazyRegistry` (refused entry points included): a plug-in
    that cannot be imported is listed with the reason, never raised."""
    rows = []
    for name, reason in registry.available().items():
        description = ""
        if reason is None:
            description = describe(registry.load(name))
        row = {"name": name, "available": reason is None, "reason": reason or "", "description": description}
        origin = _origin(registry, name)
        if origin:
            row["origin"] = origin
        elif name not in registry:  # a refused entry point, "name (distribution)"
            row["origin"] = "refused plug-in"
        rows.append(row)
    return rows


def _first_doc_line(obj) -> str:
    doc = (obj.__doc__ or "").strip().splitlines()
    return doc[0] if doc else ""


def hole_generators() -> list[dict]:
    from dpcbench.holes.registry import GENERATORS

    return _registry_rows(GENERATORS, _first_doc_line)


def methods() -> list[dict]:
    from dpcbench.methods.registry import METHODS

    return _registry_rows(METHODS, lambda cls: str(getattr(cls, "summary", "") or ""))


def metrics() -> list[dict]:
    from dpcbench.metrics.registry import METRICS

    def describe(metric) -> str:
        better = "higher" if getattr(metric, "higher_is_better", True) else "lower"
        return f"[{metric.unit}, {better} is better] {metric.description}".strip()

    return _registry_rows(METRICS, describe)


def run(args) -> int:
    sections = {
        "sequences": sequences(args.data_dir),
        "hole generators": hole_generators(),
        "methods": methods(),
        "metrics": metrics(),
    }
    if args.json:
        print(json.dumps(sections, indent=2, default=str))
        return 0
    for title, rows in sections.items():
        print(f"{title}:")
        width = max((len(r["name"]) for r in rows), default=4)
        for row in rows:
            kind = f"[{row['kind']}] " if row.get("kind") else ""
            kind += f"[{row['origin']}] " if row.get("origin") else ""
            state = "" if row["available"] else f"  (unavailable: {row['reason']})"
            print(f"  {row['name']:<{width}}  {kind}{row['description']}{state}")
        print()
    return 0
