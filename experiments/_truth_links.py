"""Link the truth frames a `dpcbench damage` folder was made from into DIR/truth, in the damage's frame order.

    python experiments/_truth_links.py DIR DATA

DIR holds the damage in DIR/damaged (its holes.json lists the input files); DATA is the folder of the sequence's
frames. Links already there are kept. Used by the shell scripts here that score a damage against its truth."""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print("usage: " + __doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        return 2
    folder, data = Path(argv[0]), Path(argv[1]).resolve()  # the links hold absolute paths
    (folder / "truth").mkdir(parents=True, exist_ok=True)
    for i, name in enumerate(json.loads((folder / "damaged" / "holes.json").read_text())["input_files"]):
        link = folder / "truth" / f"t_{i:04d}.ply"
        if not link.exists():
            os.symlink(data / name, link)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
