"""Write README.md's generated tables from the committed results (``--check``: exit 1 when stale).

Each table sits between ``<!-- generated: NAME -->`` and ``<!-- end: NAME -->`` in README.md, made by
``mistyle.benchmark.runner.table`` from a results folder's ``rows.jsonl`` (``SOURCES``): the medians
over the pairs of each method, scored as ``mistyle-render`` shows them (256^2, 64 spp, OIDN):

* ``real``: the real split (volumes that others made), ``results/benchmark-real/``;
* ``heldout``: the held-out split, ``results/solid_texture_study/heldout/`` (the rows of the methods
  in the benchmark's registry; the study's other arm is left out);
* ``heldout128``: the held-out 128^3 smoke, ``results/benchmark-heldout128/``.

    python scripts/readme_tables.py            # rewrite the blocks
    python scripts/readme_tables.py --check    # what tests/test_readme.py runs
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


SOURCES = {
    "real": ("results/benchmark-real", "the real split's pairs"),
    "heldout": ("results/solid_texture_study/heldout", "the held-out split's pairs"),
    "heldout128": ("results/benchmark-heldout128", "the held-out 128^3 smoke's pairs"),
}


def blocks() -> dict[str, str]:
    from mistyle.benchmark.methods import METHODS
    from mistyle.benchmark.runner import read_rows, table

    made = {}
    for name, (folder, pairs) in SOURCES.items():
        rows = [row for row in read_rows(ROOT / folder / "rows.jsonl") if row.method in METHODS]
        commits = sorted({row.commit for row in rows})
        made[name] = (
            f"From [`{folder}/rows.jsonl`]({folder}/) ({len(rows)} rows, commit(s) {', '.join(commits)}): medians "
            f'over {pairs}; "x uniform", "x noise" and "x tuned": medians of per-pair ratios to the uniform fill, '
            'to smooth noise + colour match and to tuned noise + colour match; "structure < ...": pairs whose '
            'structure is closer to the style than that baseline\'s; "beats uniform": pairs below the uniform '
            "fill in both SWDs; seconds to make the albedo on this project's 2-core CPU.\n\n" + table(rows)
        )
    return made


def rewritten(text: str) -> str:
    for name, body in blocks().items():
        pattern = re.compile(rf"(<!-- generated: {name} -->\n).*?(<!-- end: {name} -->)", re.S)
        if not pattern.search(text):
            raise SystemExit(f"README.md has no <!-- generated: {name} --> ... <!-- end: {name} --> block.")
        text = pattern.sub(lambda match, body=body: match.group(1) + body + match.group(2), text)
    return text


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--check", action="store_true", help="exit 1 when README.md's tables are stale")
    args = parser.parse_args()
    text = README.read_text()
    fresh = rewritten(text)
    if args.check:
        if fresh != text:
            print("README.md's generated tables are stale: run python scripts/readme_tables.py", file=sys.stderr)
            return 1
        return 0
    README.write_text(fresh)
    return 0


if __name__ == "__main__":
    sys.exit(main())
