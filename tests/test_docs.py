"""The documentation the code cites exists.

- Every ``docs/<file>.md#anchor`` the code cites (in ``src/``, ``tests/``,
  ``benchmarks/``, ``examples/``) names an anchor that file has: an explicit
  ``<a id="..."></a>`` or a heading's GitHub anchor.
- Every relative link of the README and of ``docs/*.md`` reaches a file, and its
  ``#anchor`` exists there.
- ``tools/respec.py`` maps every "SPEC section n" citation left in ``src/`` to an anchor
  of ``docs/model.md`` that exists and holds section n, so that running it leaves none
  (the citations are rewritten once, by the lead, after the helpers' work is merged).
"""

from __future__ import annotations

import importlib.util
import re
from functools import lru_cache
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
CODE_FOLDERS = ("src", "tests", "benchmarks", "examples", "tools")

_CITATION = re.compile(r"docs/(?P<file>[\w/.-]+\.md)(?P<anchors>#[\w-]+(?:(?:,| and| to)"
                       r"\s+#[\w-]+)*)")
_LINK = re.compile(r"\]\((?P<target>[^)\s]+)\)")


def _slug(heading: str) -> str:
    """GitHub's anchor of a Markdown heading."""
    text = re.sub(r"`|\*|_(?=\w)", "", heading.strip().lower())
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


@lru_cache(maxsize=None)
def anchors_of(path: Path) -> frozenset:
    """The anchors a Markdown file defines (explicit ids and headings)."""
    text = path.read_text(encoding="utf-8")
    found = set(re.findall(r'<a\s+(?:id|name)="([^"]+)"', text))
    inside_code = False
    for line in text.splitlines():
        if line.startswith("```"):
            inside_code = not inside_code
        elif not inside_code and re.match(r"#{1,6} ", line):
            found.add(_slug(line.lstrip("#")))
    return frozenset(found)


def _respec():
    spec = importlib.util.spec_from_file_location("respec", ROOT / "tools" / "respec.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def code_citations():
    """``(where, doc file, anchor)`` of every docs anchor the code cites."""
    for folder in CODE_FOLDERS:
        for path in sorted((ROOT / folder).rglob("*.py")):
            text = path.read_text(encoding="utf-8")
            for match in _CITATION.finditer(text):
                line = text.count("\n", 0, match.start()) + 1
                for anchor in re.findall(r"#([\w-]+)", match["anchors"]):
                    yield f"{path.relative_to(ROOT)}:{line}", match["file"], anchor


def test_every_docs_anchor_the_code_cites_exists():
    missing = [f"{where}: docs/{doc}#{anchor}" for where, doc, anchor in code_citations()
               if not (ROOT / "docs" / doc).is_file()
               or anchor not in anchors_of(ROOT / "docs" / doc)]
    assert not missing, "cited anchors that docs/ does not have:\n" + "\n".join(missing)


@pytest.mark.parametrize("page", ["README.md", *sorted(
    str(p.relative_to(ROOT)) for p in (ROOT / "docs").glob("*.md"))])
def test_links_between_the_pages_resolve(page):
    source = ROOT / page
    broken = []
    for match in _LINK.finditer(source.read_text(encoding="utf-8")):
        target = match["target"]
        if re.match(r"[a-z]+:", target):  # http:, https:, mailto:
            continue
        file, _, anchor = target.partition("#")
        path = (source.parent / file).resolve() if file else source
        if not path.exists():
            broken.append(f"{target}: no file {path.relative_to(ROOT)}")
        elif anchor and path.suffix == ".md" and anchor not in anchors_of(path):
            broken.append(f"{target}: no anchor #{anchor} in {path.relative_to(ROOT)}")
    assert not broken, f"{page}:\n" + "\n".join(broken)


def test_model_sections_keep_the_spec_numbers():
    """The anchor respec maps section n to sits on docs/model.md's heading "## n. ...",
    so "SPEC section n" and "model.md section n" stay the same thing."""
    respec = _respec()
    text = (ROOT / "docs" / "model.md").read_text(encoding="utf-8")
    for number, anchor in respec.ANCHORS.items():
        match = re.search(rf'<a id="{anchor}"></a>\s*\n## (\d+)\. ', text)
        assert match, f"docs/model.md has no '<a id=\"{anchor}\"></a>' before a heading"
        assert int(match[1]) == number, (anchor, match[1], number)


def test_respec_maps_every_spec_citation_of_the_code():
    respec = _respec()
    left = []
    for path in sorted((ROOT / "src").rglob("*.py")):
        new, unmapped = respec.rewrite(path.read_text(encoding="utf-8"))
        left += [f"{path.relative_to(ROOT)}: {u}" for u in unmapped + respec.remaining(new)]
        for match in _CITATION.finditer(new):
            for anchor in re.findall(r"#([\w-]+)", match["anchors"]):
                assert anchor in anchors_of(ROOT / "docs" / match["file"]), (path, anchor)
    assert not left, "citations tools/respec.py leaves:\n" + "\n".join(left)


def test_respec_rewrites_the_forms_the_code_uses():
    rewrite = _respec().rewrite
    assert rewrite("(SPEC section 3)") == ("(docs/model.md#servo-axis)", [])
    assert rewrite("SPEC sections 1, 3 and 4")[0] == (
        "docs/model.md#chain, #servo-axis and #controllers")
    assert rewrite("PD+ law, SPEC sections 3-4)")[0] == (
        "PD+ law, docs/model.md#servo-axis to #controllers)")
    assert rewrite("gains, SPEC\n    sections 3-4), the")[0] == (
        "gains,\n    docs/model.md#servo-axis to #controllers), the")
    assert rewrite("(SPEC section 10's mismatch)")[0] == (
        "(docs/model.md#beyond-the-paper: the mismatch)")
    assert rewrite("(SPEC eq. 3.3)")[0] == "(eq. 3.3 (docs/model.md#controllers))"
    assert rewrite("SPEC section 99")[1] == ["'SPEC section 99' (section 99)"]


def test_the_readme_library_example_runs(tmp_path, monkeypatch, capsys):
    """The README's Python block runs as written and prints what its comments say."""
    text = (ROOT / "README.md").read_text(encoding="utf-8")
    blocks = re.findall(r"```python\n(.*?)```", text, re.S)
    assert len(blocks) == 1
    monkeypatch.chdir(tmp_path)
    exec(compile(blocks[0], "README.md", "exec"), {})
    printed = capsys.readouterr().out.splitlines()
    promised = re.findall(r"print\(.*?#\s*(.+)$", blocks[0], re.M)
    assert printed == [p.strip() for p in promised]
    assert any((tmp_path / "out" / "figures").iterdir())
