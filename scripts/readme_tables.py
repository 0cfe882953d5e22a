"""Write README.md's generated tables from the committed results (``--check``: exit 1 when stale).

Each table sits between ``<!-- generated: NAME -->`` and ``<!-- end: NAME -->`` in README.md:

* ``benchmark``: the held-out benchmark's medians per method, ``mistyle.benchmark.runner.table`` of
  ``results/benchmark/rows.jsonl``.

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


def blocks() -> dict[str, str]:
    from mistyle.benchmark.runner import read_rows, table

    rows = read_rows(ROOT / "results" / "benchmark" / "rows.jsonl")
    commits = sorted({row.commit for row in rows})
    source = (
        f"From `results/benchmark/rows.jsonl` ({len(rows)} rows, commit(s) {', '.join(commits)}): "
        'medians over the held-out pairs; "x uniform", "x noise" and "x tuned" are the medians of per-pair ratios '
        "to the uniform baseline, to smooth noise + colour match and to tuned noise + colour match (the strongest "
        'training-free field); "structure < ...": pairs whose structure is closer to the style than that '
        'baseline\'s; "beats uniform": pairs lower than the uniform baseline in both SWDs; seconds to make the '
        "albedo on this project's 2-core CPU.\n\n"
    )
    return {"benchmark": source + table(rows)}


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
