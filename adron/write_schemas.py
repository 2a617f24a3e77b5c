"""Write the JSON Schema of every user file format into ``adron/schemas/`` (package data):
``python -m adron.write_schemas`` (``make schemas``); ``--check`` only compares, exit 1
when a committed file differs from what the models give (tests/adron/test_schema.py does too).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

from adron.formats import schemas

FOLDER = Path(__file__).parent / "schemas"


def rendered() -> dict[str, str]:
    """file name -> text of each schema file."""

    return {
        f"{name}.schema.json": json.dumps(schema, indent=2, sort_keys=True, ensure_ascii=False)
        + "\n"
        for name, schema in sorted(schemas().items())
    }


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    files = rendered()
    if "--check" in argv:
        stale = [
            n
            for n, t in files.items()
            if not (FOLDER / n).is_file() or (FOLDER / n).read_text(encoding="utf-8") != t
        ]
        for n in stale:
            print(f"adron/schemas/{n}: differs from the models (run python -m adron.write_schemas)")
        return 1 if stale else 0
    FOLDER.mkdir(exist_ok=True)
    for n, t in files.items():
        tmp = FOLDER / f".{n}.tmp"
        tmp.write_text(t, encoding="utf-8")
        tmp.replace(FOLDER / n)
    print(f"wrote {len(files)} schemas into adron/schemas/")
    return 0


if __name__ == "__main__":
    sys.exit(main())
