"""Keep numba's on-disk caches of this package consistent with its sources (private).

numba's ``cache=True`` checks only the source file of the function it loads, but a
compiled loop embeds functions from other modules (an interpolator's step inside the
closed loop): after an edit of one module, another module's cache would still hold the old
code. So, once per import, a digest of every source file of the package is compared with
the one stored beside the caches, and on a difference the package's cache files are
removed (numba then compiles afresh and writes new ones). An installed, unchanged package
pays one digest of its sources (about 1 ms); an unwritable install is left alone.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

_PACKAGE = Path(__file__).resolve().parents[1]
_STAMP = _PACKAGE / "__pycache__" / "nurbsmotion-jit-sources.sha256"


def sources_digest() -> str:
    """SHA-256 of the package's Python sources (paths and contents)."""
    h = hashlib.sha256()
    for f in sorted(_PACKAGE.rglob("*.py")):
        h.update(str(f.relative_to(_PACKAGE)).encode())
        h.update(f.read_bytes())
    return h.hexdigest()


def drop_stale_caches() -> None:
    """Remove the package's numba cache files if its sources changed since they were made."""
    try:
        digest = sources_digest()
        if _STAMP.is_file() and _STAMP.read_text() == digest:
            return
        for f in _PACKAGE.rglob("__pycache__/*.nb[ic]"):
            f.unlink(missing_ok=True)
        _STAMP.parent.mkdir(exist_ok=True)
        _STAMP.write_text(digest)
    except OSError:  # a read-only install: its caches were made from these very sources
        pass
