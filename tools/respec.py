"""Rewrite the code's "SPEC section n" citations to the anchors of docs/model.md.

The specification the code was written against now lives in the repository, in
``docs/model.md``, whose sections keep the SPEC's numbers and carry stable anchors
(``<a id="servo-axis"></a>``). This script rewrites, in every ``.py`` file under the
given folders (default ``src``):

- ``SPEC section 3``                -> ``docs/model.md#servo-axis``
- ``SPEC sections 1 and 4``         -> ``docs/model.md#chain and #controllers``
- ``SPEC sections 3-4``             -> ``docs/model.md#servo-axis to #controllers``
- ``SPEC section 9 and 10``         -> ``docs/model.md#run-figures and #beyond-the-paper``
- ``SPEC eq. 3.3``                  -> ``eq. 3.3 (docs/model.md#controllers)``
- ``(SPEC section 5's one-sided rule)`` -> ``(docs/model.md#interpolation: the one-sided rule)``

    python tools/respec.py            # rewrite src/ in place, list what changed
    python tools/respec.py --check    # change nothing; exit 1 if a citation is left

A citation it cannot map (a section number with no anchor) is reported and left as it
is. ``tests/test_docs.py`` checks that every anchor this script produces, and every
``docs/<file>.md#anchor`` the code cites, exists.
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOC = "docs/model.md"

ANCHORS = {
    1: "chain",
    2: "units",
    3: "servo-axis",
    4: "controllers",
    5: "interpolation",
    6: "speed-bound",
    7: "paper-algorithm",
    8: "benchmarks",
    9: "run-figures",
    10: "beyond-the-paper",
    11: "real-machine",
}
"""SPEC section number -> the anchor of docs/model.md holding it."""

EQUATIONS = {"3.3": 4, "3.6": 6, "2.1": 3, "2.2": 3, "2.4": 4, "2.12": 4}
"""An equation the SPEC cites -> the section that states it."""

_SECTIONS = re.compile(r"(?P<pre> ?)SPEC(?P<gap>\s+)sections?\s+(?P<first>\d+)"
                       r"(?P<rest>(?:(?:, | and |-|–)\d+)*)(?P<own>'s)?")
_EQUATION = re.compile(r"SPEC eq\. (?P<eq>\d+\.\d+)")


class Unmapped(Exception):
    pass


def _anchor(n: int) -> str:
    if n not in ANCHORS:
        raise Unmapped(f"section {n}")
    return ANCHORS[n]


def _sections(match: re.Match) -> str:
    first = int(match["first"])
    text = f"{DOC}#{_anchor(first)}"
    for sep, number in re.findall(r"(, | and |-|–)(\d+)", match["rest"]):
        joiner = " to " if sep in "-–" else sep
        text += f"{joiner}#{_anchor(int(number))}"
    if match["own"]:  # "SPEC section 5's one-sided rule" -> "docs/...#interpolation: the ..."
        text += ": the"
    gap = match["gap"]
    if "\n" in gap:  # "SPEC" ended a line: the citation starts the next one
        return "\n" + gap.rsplit("\n", 1)[1] + text
    return match["pre"] + text


def _equation(match: re.Match) -> str:
    eq = match["eq"]
    if eq not in EQUATIONS:
        raise Unmapped(f"eq. {eq}")
    return f"eq. {eq} ({DOC}#{_anchor(EQUATIONS[eq])})"


def rewrite(text: str) -> tuple[str, list[str]]:
    """``text`` with its SPEC citations rewritten, and the citations left unmapped."""
    left = []

    def safe(fn):
        def inner(match):
            try:
                return fn(match)
            except Unmapped as exc:
                left.append(f"{match.group(0)!r} ({exc})")
                return match.group(0)
        return inner

    text = _EQUATION.sub(safe(_equation), text)
    text = _SECTIONS.sub(safe(_sections), text)
    return text, left


def remaining(text: str) -> list[str]:
    """The "SPEC ..." citations still in ``text``."""
    return re.findall(r"SPEC[\s.]\S+(?:\s\S+)?", text)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("folders", nargs="*", default=["src"])
    parser.add_argument("--check", action="store_true", help="change nothing")
    args = parser.parse_args(argv)
    changed, left = 0, []
    for folder in args.folders:
        for path in sorted((ROOT / folder).rglob("*.py")):
            old = path.read_text(encoding="utf-8")
            new, unmapped = rewrite(old)
            left += [f"{path.relative_to(ROOT)}: {u}" for u in unmapped]
            left += [f"{path.relative_to(ROOT)}: {r!r}" for r in remaining(new)
                     if not unmapped]
            if new != old:
                changed += 1
                if not args.check:
                    path.write_text(new, encoding="utf-8")
                print(f"{'would rewrite' if args.check else 'rewrote'} "
                      f"{path.relative_to(ROOT)}")
    for item in left:
        print(f"not mapped: {item}", file=sys.stderr)
    if args.check:
        return 1 if changed or left else 0
    return 1 if left else 0


if __name__ == "__main__":
    raise SystemExit(main())
