"""File plumbing shared by the path readers/writers and the exporters (private).

Readers check a file before parsing it (exists, is a file, not absurdly large) so that a
wrong argument fails at once with one clear :class:`PathFileError`. Writers never
overwrite an existing file unless asked, and write through a temporary file in the same
folder that is renamed into place only when complete, so a failed export leaves nothing
behind.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path
from typing import Callable, IO

from .errors import OutputExistsError, PathFileError

__all__ = ["check_input_file", "write_output"]


def check_input_file(file: str | os.PathLike, max_bytes: int | None = None) -> Path:
    """Return ``file`` as a Path after checking it exists, is a file and is not too big.

    Raises
    ------
    PathFileError
        Naming the file, if it is missing, a folder, or larger than ``max_bytes``.
    """
    path = Path(file)
    if not path.exists():
        raise PathFileError("no such file", source=str(path))
    if not path.is_file():
        raise PathFileError("not a regular file (a folder?)", source=str(path))
    if max_bytes is not None:
        size = path.stat().st_size
        if size > max_bytes:
            raise PathFileError(
                f"file is {size / 1e6:.1f} MB, more than the {max_bytes / 1e6:.0f} MB a "
                "path file of this format may have; is it the right file?",
                source=str(path),
            )
    return path


def write_output(
    file: str | os.PathLike,
    write: Callable[[IO], None],
    *,
    overwrite: bool = False,
    binary: bool = False,
) -> Path:
    """Write ``file`` with ``write(handle)``, atomically and without clobbering.

    Parameters
    ----------
    file : str or path-like
        Target file; its folder must exist.
    write : callable
        Called with an open handle (text, UTF-8, or binary) of a temporary file.
    overwrite : bool
        Replace an existing ``file``; otherwise an existing file is an error.
    binary : bool
        Open the temporary file in binary mode.

    Returns
    -------
    Path
        The written file.

    Raises
    ------
    OutputExistsError
        If ``file`` exists and ``overwrite`` is false (nothing is written).
    """
    path = Path(file)
    if path.exists() and not overwrite:
        raise OutputExistsError(
            f"{path}: file exists; refusing to overwrite it (pass overwrite=True to replace it)"
        )
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise PathFileError("output folder does not exist", source=str(folder))
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=folder)
    try:
        mode = "wb" if binary else "w"
        kwargs = {} if binary else {"encoding": "utf-8", "newline": "\n"}
        with os.fdopen(fd, mode, **kwargs) as handle:
            write(handle)
        # mkstemp makes the file private (0600); give it the permissions open() would
        mask = os.umask(0)
        os.umask(mask)
        os.chmod(tmp, 0o666 & ~mask)
        if not overwrite and path.exists():  # appeared while we were writing
            raise OutputExistsError(f"{path}: file exists; refusing to overwrite it")
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.unlink(tmp)
        raise
    return path
