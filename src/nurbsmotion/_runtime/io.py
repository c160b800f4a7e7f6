"""File plumbing shared by the path readers/writers and the exporters (private).

Readers check a file before parsing it (exists, is a file, not absurdly large) so that a
wrong argument fails at once with one clear :class:`PathFileError`. Writers never
overwrite an existing file unless asked, and write through a temporary file in the same
folder that is renamed into place only when complete, so a failed export leaves nothing
behind.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import sys
import tempfile
from pathlib import Path
from contextlib import contextmanager
from typing import IO, Callable, Iterator

from ..errors import InvalidArgumentError, OutputExistsError, PathFileError

__all__ = ["json_safe", "check_input_file", "read_text_file", "parse_json_or_toml", "write_output",
           "atomic_output", "OutputFolder"]


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


def read_text_file(file: str | os.PathLike, max_bytes: int | None = None) -> str:
    """The text of a UTF-8 file, checked as :func:`check_input_file` does.

    A leading byte-order mark (which Windows editors write) is dropped, and CRLF and CR
    line ends are read as LF.

    Raises
    ------
    PathFileError
        Naming the file (and the line) if it is missing, too big or not UTF-8.
    """
    path = check_input_file(file, max_bytes)
    data = path.read_bytes()
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[: exc.start].count(b"\n") + 1
        raise PathFileError("not a UTF-8 text file", str(path), line) from None
    return text.replace("\r\n", "\n").replace("\r", "\n")


def parse_json_or_toml(text: str, *, toml: bool, source: str, constants: bool = False):
    """Parse JSON or TOML text; every syntax fault is one :class:`PathFileError`.

    Parameters
    ----------
    text : str
        The file's text.
    toml : bool
        TOML if true, else JSON.
    source : str
        File name for the messages.
    constants : bool
        Accept JSON's non-standard ``NaN``, ``Infinity`` and ``-Infinity``.

    Raises
    ------
    PathFileError
        Naming the file and, where the parser gives it, the line: a syntax error, a
        non-standard constant, or nesting deeper than the parser's recursion limit.
    """
    try:
        if toml:
            if sys.version_info >= (3, 11):
                import tomllib
            else:  # pragma: no cover - Python 3.10
                import tomli as tomllib
            try:
                return tomllib.loads(text)
            except tomllib.TOMLDecodeError as exc:
                match = re.search(r"line (\d+)", str(exc))
                message = re.sub(r"\s*\(at line \d+, column \d+\)|\s*\(at end of document\)",
                                 "", str(exc))
                raise PathFileError(f"not valid TOML: {message}", source,
                                    int(match.group(1)) if match else None) from None
            except ValueError as exc:  # an integer beyond Python's digit limit
                raise PathFileError(f"not valid TOML: {_one_line(exc)}", source) from None
        try:
            return json.loads(text, parse_constant=None if constants else _reject_constant)
        except json.JSONDecodeError as exc:
            raise PathFileError(f"not valid JSON: {exc.msg} (column {exc.colno})", source,
                                exc.lineno) from None
        except ValueError as exc:  # NaN/Infinity refused, or an integer beyond the digit limit
            raise PathFileError(f"not valid JSON: {_one_line(exc)}", source) from None
    except RecursionError:
        raise PathFileError(
            "nested deeper than the parser can follow (lists or tables inside each other "
            f"about {sys.getrecursionlimit()} deep or more); this is not a path or machine file",
            source) from None


def _reject_constant(name: str):
    raise ValueError(f"{name} is not a number a file may hold")


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split())


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
    with atomic_output(file, overwrite=overwrite, binary=binary) as handle:
        write(handle)
    return Path(file)


@contextmanager
def atomic_output(file: str | os.PathLike, *, overwrite: bool = False,
                  binary: bool = False) -> Iterator[IO]:
    """An open handle of a temporary file in ``file``'s folder, renamed to ``file`` when
    the ``with`` block ends normally and removed when it raises (see :func:`write_output`
    for the parameters and errors)."""
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
            yield handle
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


class OutputFolder:
    """The files one command writes into a folder: all of them, or none.

    The names a command writes are declared once, up front, and checked before any
    work: none of them may exist unless ``overwrite`` (so a refused command changes
    nothing the user has). Inside the ``with`` block the command writes into
    :attr:`staging`, a hidden temporary folder inside the target folder. When the block
    completes, every file there is moved into place (a file that was not declared is
    checked the same way first, so a forgotten name can never overwrite); when it fails
    or is interrupted, the staging folder is removed and no file appears under a final
    name (and a folder the command created is removed again if it is empty).

    A folder holds one run's outputs, never two runs' mixed: ``replaces`` names every file
    an earlier command may have written there (the project's outputs). Without
    ``overwrite`` any of them that exists refuses the command; with it, those the
    command did not write this time are removed once its own files are in place. No
    other file of the folder is ever touched.

    Parameters
    ----------
    folder : path-like
        The output folder (created, with its parents, on entering the block); not empty.
    names : iterable of str
        Every file name the command may write there.
    overwrite : bool
        Replace existing files of those names, and remove the ``replaces`` it does not
        write.
    replaces : iterable of str
        The file names an earlier run may have left there (``names`` are added).

    Raises
    ------
    OutputExistsError
        If a declared (or ``replaces``) file exists and ``overwrite`` is false.
    PathFileError
        If the folder is a file, lies under a file, or cannot be written.
    InvalidArgumentError
        If the folder's name is empty.
    """

    def __init__(self, folder, names, *, overwrite: bool = False, replaces=()):
        if not str(folder).strip():
            raise InvalidArgumentError(f"the output folder name {str(folder)!r} is empty; name "
                                       "a folder ('.' for the current one)")
        self.folder = Path(folder)
        self.names = tuple(names)
        self.replaces = tuple(dict.fromkeys((*self.names, *replaces)))
        self.overwrite = overwrite
        self.staging: Path | None = None
        self._created: list[Path] = []
        self._check_folder()
        self.check(self.replaces)

    def _check_folder(self) -> None:
        folder = self.folder
        if folder.exists() and not folder.is_dir():
            raise PathFileError("the output folder is a file, not a folder", source=str(folder))
        existing = folder
        while not existing.exists():
            existing = existing.parent
        if not existing.is_dir():
            raise PathFileError(f"cannot create the output folder: {existing} is a file",
                                source=str(folder))
        if not os.access(existing, os.W_OK | os.X_OK):
            raise PathFileError("cannot write to this folder (permission denied)",
                                source=str(existing))

    def check(self, names) -> None:
        """Raise :class:`OutputExistsError` if one of ``names`` exists in the folder."""
        if self.overwrite:
            return
        existing = [n for n in names if os.path.lexists(self.folder / n)]
        if existing:
            more = f" (and {len(existing) - 1} more of its outputs)" if len(existing) > 1 else ""
            raise OutputExistsError(
                f"{self.folder / existing[0]} exists{more}; choose another output folder or "
                "pass --overwrite"
            )

    def __enter__(self) -> "OutputFolder":
        missing = self.folder
        while not missing.exists():
            self._created.append(missing)
            missing = missing.parent
        self.folder.mkdir(parents=True, exist_ok=True)
        self.staging = Path(tempfile.mkdtemp(prefix=".nurbsmotion-", suffix=".tmp",
                                             dir=self.folder))
        return self

    def __exit__(self, exc_type, exc, tb) -> bool:
        ok = False
        try:
            if exc_type is None:
                self._commit()
                ok = True
        finally:
            shutil.rmtree(self.staging, ignore_errors=True)
            if not ok:
                for folder in self._created:  # innermost first
                    try:
                        folder.rmdir()
                    except OSError:
                        break
        return False

    def _commit(self) -> None:
        files = sorted(p.name for p in self.staging.iterdir())
        self.check(files)  # declared or not, and in case one appeared meanwhile
        moved = []
        try:
            for name in files:
                os.replace(self.staging / name, self.folder / name)
                moved.append(name)
        except BaseException:
            if not self.overwrite:  # the moved ones were new: take them back
                for name in moved:
                    os.unlink(self.folder / name)
            raise
        if self.overwrite:  # an earlier run's outputs this one did not write
            for name in self.replaces:
                stale = self.folder / name
                if name not in moved and (stale.is_file() or stale.is_symlink()):
                    stale.unlink()


def json_safe(value):
    """``value`` with every float that is not finite replaced by None (JSON has no inf or
    NaN), through dicts, lists and tuples."""
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value
