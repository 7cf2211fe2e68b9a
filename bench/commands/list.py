"""`dpcbench list`: the sequences, hole generators, methods and metrics this install knows, each with
whether it can be used here and, when not, why."""

from __future__ import annotations

import json


def register(subparsers) -> None:
    parser = subparsers.add_parser("list", help="list sequences, hole generators, methods and metrics",
                                   description=__doc__)
    parser.add_argument("--data-dir", default=None,
                        help="folder holding the paper's sequences (default: $DPCBENCH_DATA_DIR)")
    parser.add_argument("--json", action="store_true", help="print one JSON object instead of text")
    parser.set_defaults(func=run)


def _reason(err: BaseException) -> str:
    return f"{type(err).__name__}: {err}"


def sequences(data_dir) -> list[dict]:
    from dpcbench.bench.datasets import describe_datasets

    rows = describe_datasets(data_dir)
    for row in rows:
        if row.get("params"):
            row["description"] += "; params: " + ", ".join(f"{k}={v!r}" for k, v in row["params"].items())
        row.pop("params", None)
    return rows


def hole_generators() -> list[dict]:
    from dpcbench.holes.registry import GENERATORS, generator_class

    rows = []
    for name in sorted(GENERATORS):
        try:
            cls = generator_class(name)
            doc = (cls.__doc__ or "").strip().splitlines()
            rows.append({"name": name, "available": True, "reason": "", "description": doc[0] if doc else ""})
        except ImportError as err:  # an optional dependency of the generator is missing here
            rows.append({"name": name, "available": False, "reason": _reason(err), "description": ""})
    return rows


def methods() -> list[dict]:
    from dpcbench.methods.registry import available_methods, method_class

    status = available_methods()
    rows = []
    for name, reason in status.items():
        summary = ""
        if reason is None:
            summary = str(getattr(method_class(name), "summary", "") or "")
        rows.append({"name": name, "available": reason is None, "reason": reason or "", "description": summary})
    return rows


def metrics() -> list[dict]:
    from dpcbench.metrics.registry import METRICS

    rows = []
    for name, metric in METRICS.items():
        better = "higher" if getattr(metric, "higher_is_better", True) else "lower"
        unit = getattr(metric, "unit", "")
        desc = getattr(metric, "description", "")
        rows.append({"name": name, "available": True, "reason": "",
                     "description": f"[{unit}, {better} is better] {desc}".strip()})
    return rows


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
            state = "" if row["available"] else f"  (unavailable: {row['reason']})"
            print(f"  {row['name']:<{width}}  {kind}{row['description']}{state}")
        print()
    return 0
