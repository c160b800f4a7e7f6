"""JSON and TOML path files, and the dispatch from a file name or built-in name to a curve.

File format
-----------
A path file holds one NURBS curve, the fields of :meth:`NurbsCurve.to_dict`:

=================  ===========================  =============================================
field              type                         meaning
=================  ===========================  =============================================
``degree``         integer >= 1                 polynomial degree p
``knots``          list of n + p + 1 numbers    clamped, non-decreasing (normalised to [0, 1])
``control_points`` list of n lists of numbers   one row per point, one column per axis
``weights``        list of n numbers, optional  positive; all 1 when omitted
``name``           string, optional             label carried into reports
``units``          string, optional             length unit of the control points
``source``,        string, optional             free text, ignored by the reader
``description``
=================  ===========================  =============================================

The JSON form is the one of ``paths/data/die_bonder_pi.json``; the TOML form has the same
keys at the top level. Any other key is an error (it is most likely a misspelt field).
Numbers are written with Python's shortest round-trip ``repr``, so load and save
round-trip exactly, bit for bit.

Every problem raises one :class:`~nurbsmotion.errors.PathFileError` that names the file,
the field and, where it can be found, the line.
"""

from __future__ import annotations

import json
import math
import os
import re
import itertools
import warnings
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import tomli_w

from dataclasses import dataclass

from .._runtime.io import check_input_file, parse_json_or_toml, read_text_file, write_output
from ..feed import FeedLimit
from ..errors import (InvalidArgumentError, InvalidCurveError, NurbsmotionError, PathFileError,
                      WorkLimitError)
from ..limits import PATH_UNITS
from ..nurbs import BUILTIN_PATHS, MAX_CONTROL_POINTS, NurbsCurve, builtin_path

if TYPE_CHECKING:  # (annotation only)
    from ..chords import ChordJoin

__all__ = [
    "Contour",
    "load_contours",
    "PathWarning",
    "PATH_UNITS",
    "load_path",
    "save_path",
    "resolve_path",
    "curve_from_dict",
    "PATH_FILE_SUFFIXES",
    "MAX_PATH_FILE_BYTES",
    "SIZE_SCAN_BYTES",
]

MAX_PATH_FILE_BYTES = 32_000_000
"""Largest JSON/TOML path file read [byte]; a 10^5-point path takes about 5 MB."""

_GCODE_SUFFIXES = (".ngc", ".nc", ".gcode", ".tap", ".cnc")
PATH_FILE_SUFFIXES = (".json", ".toml", ".dxf") + _GCODE_SUFFIXES
"""File name endings :func:`load_path` and :func:`resolve_path` understand."""


class PathWarning(UserWarning):
    """A path file was read under an assumption (e.g. no unit given: millimetres)."""


@dataclass(frozen=True)
class Contour:
    """One path of a file, with what the file says about it.

    Attributes
    ----------
    curve : NurbsCurve
        The path [``curve.units``].
    feed : FeedLimit or None
        The programmed feed along it [path units / s] (G-code F words); None when the
        file gives none.
    source : str
        The file (or built-in name) and contour, e.g. ``"part.ngc#2"``.
    axes : str or None
        The file's name of each column of the curve (``"XYZ"``, ``"XYC"``) where the file
        names its axes (G-code, DXF), else None.
    units_source : str or None
        Where ``curve.units`` came from: ``"G21 on line 3"``, ``"the DXF header
        ($INSUNITS)"``, ``"the file's units field"``, ``"--units"``, ``"assumed: ..."``.
    joined : ChordJoin or None
        Where the contour's chord runs were joined into smooth curves for a run
        (:func:`nurbsmotion.run_input.load_run_contour`), what was joined; else None.
    feed_ratio : ndarray, shape (n_pieces,), or None
        Per piece of ``feed``, the speed along ``curve`` per unit of F, where they differ:
        a path whose rotary axes were rescaled to run on a machine
        (:func:`nurbsmotion.run_input.load_run_contour`, LinuxCNC's feed rule); None: 1.
    """

    curve: NurbsCurve
    feed: FeedLimit | None
    source: str
    axes: str | None = None
    units_source: str | None = None
    joined: "ChordJoin | None" = None
    feed_ratio: Any = None


_REQUIRED = ("degree", "knots", "control_points")
_OPTIONAL = ("weights", "name", "units", "source", "description")


# ---------------------------------------------------------------------- schema
def _line_of(text: str | None, field: str, toml: bool) -> int | None:
    """1-based line where ``field`` is defined in ``text`` (None if not found)."""
    if text is None:
        return None
    field = field.split("[")[0]
    pattern = rf"^\s*{re.escape(field)}\s*=" if toml else rf'"{re.escape(field)}"\s*:'
    match = re.search(pattern, text, flags=re.MULTILINE)
    return text.count("\n", 0, match.start()) + 1 if match else None


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def _numbers(value: Any, field: str) -> np.ndarray | list[float]:
    if not isinstance(value, list):
        raise _FieldError(field, f"must be a list of numbers, got {type(value).__name__}")
    if set(map(type, value)) <= {float, int}:  # the common case, checked in C loops
        try:
            table = np.array(value, dtype=float)
        except OverflowError:  # an integer beyond a double: named below
            table = None
        if table is not None and np.isfinite(table).all():
            return table
    for i, x in enumerate(value):
        if not _is_number(x):
            raise _FieldError(field, f"entry {i} is {x!r} ({type(x).__name__}); expected a number")
        try:
            finite = math.isfinite(x)
        except OverflowError:  # an integer of hundreds of digits
            raise _FieldError(field, f"entry {i} ({str(x)[:20]}..., {len(str(x))} digits) is "
                              "too large for double precision") from None
        if not finite:
            raise _FieldError(field, f"entry {i} is {x!r}; expected a finite number")
    return [float(x) for x in value]


def _number_rows(points: list) -> Any:
    """``control_points`` as rows of finite numbers: one array conversion when every entry
    is a plain int or float (a million rows in a fraction of a second), else row by row
    with :func:`_numbers`, which names the bad entry."""
    if set(map(type, points)) == {list} and set(
            map(type, itertools.chain.from_iterable(points))) <= {float, int}:  # in C
        try:
            table = np.array(points, dtype=float)
        except (ValueError, OverflowError):  # ragged rows, an integer beyond a double
            table = None
        if table is not None and table.ndim == 2 and np.isfinite(table).all():
            return table
    return [_numbers(row, f"control_points[{i}]") for i, row in enumerate(points)]


class _FieldError(Exception):
    def __init__(self, field: str, message: str):
        super().__init__(f"field {field!r} {message}")
        self.field = field


def _check_fields(data: Any) -> dict:
    if not isinstance(data, dict):
        raise _FieldError("<top level>", f"must be a table/object of fields, got {type(data).__name__}")
    for key in data:
        if key not in _REQUIRED + _OPTIONAL:
            raise _FieldError(
                key, f"is not a path-file field; expected {', '.join(_REQUIRED + _OPTIONAL)}"
            )
    for key in _REQUIRED:
        if key not in data:
            raise _FieldError(key, "is missing (required: degree, knots, control_points)")
    degree = data["degree"]
    if not (isinstance(degree, int) and not isinstance(degree, bool)):
        raise _FieldError("degree", f"must be an integer, got {degree!r}")
    points = data["control_points"]
    if not isinstance(points, list) or not points:
        raise _FieldError("control_points", "must be a non-empty list of [x, y, ...] rows")
    if len(points) > MAX_CONTROL_POINTS:  # refused before its rows are checked one by one
        raise _FieldError("control_points", f"has {len(points):,} rows, more than the "
                          f"{MAX_CONTROL_POINTS:,} a path may have (nurbs.MAX_CONTROL_POINTS)")
    rows = _number_rows(points)
    if not isinstance(rows, np.ndarray) and len({len(r) for r in rows}) != 1:  # ragged
        lengths = [len(r) for r in rows]
        i = next(i for i, n in enumerate(lengths) if n != lengths[0])
        raise _FieldError(
            "control_points",
            f"rows must all have the same number of axes: row 0 has {lengths[0]}, row {i} has "
            f"{lengths[i]}",
        )
    out = {"degree": degree, "knots": _numbers(data["knots"], "knots"), "control_points": rows}
    if "weights" in data:
        out["weights"] = _numbers(data["weights"], "weights")
    for key in ("name", "units", "source", "description"):
        if key in data and not isinstance(data[key], str):
            raise _FieldError(key, f"must be a string, got {data[key]!r}")
    return out | {k: data[k] for k in ("name", "units") if k in data}


def curve_from_dict(
    data: Any, source: str | None = None, text: str | None = None, toml: bool = False
) -> NurbsCurve:
    """Build a curve from a parsed path file, raising :class:`PathFileError` on any fault.

    Parameters
    ----------
    data : dict
        Parsed JSON/TOML (see the module docstring for the fields).
    source : str, optional
        File name for the messages.
    text, toml : optional
        The file's text and whether it is TOML, used to find the line of a bad field.
    """
    try:
        fields = _check_fields(data)
    except _FieldError as exc:
        raise PathFileError(str(exc), source=source, line=_line_of(text, exc.field, toml)) from None
    units = fields.get("units")
    if units is None:
        units = "mm"
        warnings.warn(f"{source or 'path'}: no 'units' field; reading millimetres (give --units "
                      "to choose)", PathWarning, stacklevel=3)
    try:
        return NurbsCurve(
            fields["degree"],
            fields["knots"],
            fields["control_points"],
            fields.get("weights"),
            name=fields.get("name"),
            units=units,
        )
    except InvalidCurveError as exc:
        raise PathFileError(f"invalid curve: {exc}", source=source) from None


# ---------------------------------------------------------------------- JSON / TOML
SIZE_SCAN_BYTES = 1_000_000
"""A JSON or TOML path file larger than this [byte] has its knot spans counted from its
text, before it is parsed, when the command gives a ``size_check``
(:func:`load_contours`): parsing takes about 45 ns of CPU a byte (a 24 MB file of a
million control points, a second), counting its knot vector's commas 0.5 ns."""


def _read_json(path: Path, size_check=None, polyline_check=None) -> NurbsCurve:
    text = read_text_file(path, MAX_PATH_FILE_BYTES)
    _scan_spans(text, False, size_check, path)
    _scan_polyline(text, False, polyline_check, path)
    data = parse_json_or_toml(text, toml=False, source=str(path))
    return curve_from_dict(data, str(path), text, toml=False)


def _read_toml(path: Path, size_check=None, polyline_check=None) -> NurbsCurve:
    text = read_text_file(path, MAX_PATH_FILE_BYTES)
    _scan_spans(text, True, size_check, path)
    _scan_polyline(text, True, polyline_check, path)
    data = parse_json_or_toml(text, toml=True, source=str(path))
    return curve_from_dict(data, str(path), text, toml=True)


def _degree_and_list(text: str, toml: bool, field: str) -> tuple[list[str], list]:
    """A path file's text's ``degree`` values (as written) and the openings of its list
    ``field`` (``re`` matches, each ending after the ``[``)."""
    if toml:
        flags = re.MULTILINE
        return (re.findall(r"^[ \t]*degree[ \t]*=[ \t]*(\d+)[ \t]*$", text, flags),
                list(re.finditer(rf"^[ \t]*{field}[ \t]*=[ \t]*\[", text, flags)))
    return (re.findall(r'"degree"\s*:\s*(\d+)\s*[,}]', text),
            list(re.finditer(rf'"{field}"\s*:\s*\[', text)))


def _scan_spans(text: str, toml: bool, size_check, path: Path) -> None:
    """Call ``size_check(degree, spans)`` with the knot spans of a large path file's text
    (:data:`SIZE_SCAN_BYTES`), before it is parsed, and say which file a refusal is of.

    Only where the count is the path's as it runs: one ``degree`` and one ``knots`` field
    holding plain numbers, and no interior knot of multiplicity p (no C0 joint: chord
    runs, joined by a run into fewer spans, only exist between such joints). Anything
    else is left to the parser and the checks after it. The spans are first bounded by
    the knots' count (their commas), and counted exactly (distinct knots) only when the
    bound is refused.
    """
    if size_check is None or len(text) <= SIZE_SCAN_BYTES:
        return
    degree, knots = _degree_and_list(text, toml, "knots")
    if len(degree) != 1 or len(knots) != 1 or not 1 <= int(degree[0]) <= 100:
        return
    p = int(degree[0])
    end = text.find("]", knots[0].end())
    body = text[knots[0].end():end].strip().rstrip(",")
    if end < 0 or not body or re.search(r"[^0-9eE+\-.,\s]", body):
        return
    most = body.count(",") + 1 - 2 * p - 1  # spans if every knot is distinct
    try:
        size_check(p, most)
        return
    except WorkLimitError:
        pass
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        try:
            t = np.fromstring(body, sep=",")
        except (ValueError, DeprecationWarning):
            return
    if t.size != body.count(",") + 1 or not np.all(np.isfinite(t)) or np.any(np.diff(t) < 0):
        return  # the parser names what is wrong
    values, counts = np.unique(t, return_counts=True)
    if np.any(counts[1:-1] >= p):
        return
    try:
        size_check(p, len(values) - 1)
    except WorkLimitError as exc:
        raise WorkLimitError(f"{path}: {exc}") from None


_ROW_TEXT = re.compile(r"[^0-9eE+\-.,\[\]\s]")
"""A character that no row of plain numbers holds."""


def _scan_polyline(text: str, toml: bool, polyline_check, path: Path) -> None:
    """Call ``polyline_check(rows, units)`` for a large degree-1 path file's text
    (:data:`SIZE_SCAN_BYTES`), before it is parsed, and say which file a refusal is of:
    ``rows(k)`` gives its first control points, at most ``k``, shape (m, n_axes), and
    whether they are all of them (None where they are not rows of plain numbers of one
    length); ``units`` is its ``units`` field (None where it has none).

    Only for one ``degree`` field of 1, one ``control_points`` list and at most one
    ``units`` string; anything else is left to the parser. The rows are read from the
    text as numbers (Python's ``float``, as the parser reads them), only as many as asked.
    """
    if polyline_check is None or len(text) <= SIZE_SCAN_BYTES:
        return
    degree, points = _degree_and_list(text, toml, "control_points")
    flags = re.MULTILINE
    if toml:
        units = re.findall(r'^[ \t]*units[ \t]*=[ \t]*"([^"\\]*)"[ \t]*$', text, flags)
        named = len(re.findall(r"^[ \t]*units[ \t]*=", text, flags))
    else:
        units = re.findall(r'"units"\s*:\s*"([^"\\]*)"', text)
        named = text.count('"units"')
    if degree != ["1"] or len(points) != 1 or len(units) != named or named > 1:
        return
    start = points[0].end()

    def rows(k: int):
        """The first rows, at most ``k``, and whether they are all; or None."""
        size = 64 * k + 4096
        while True:
            chunk = text[start:start + size]
            b = np.frombuffer(chunk.encode("ascii", "replace"), dtype=np.uint8)
            opens, closes = np.flatnonzero(b == 91), np.flatnonzero(b == 93)
            m = min(opens.size, closes.size, k)
            if m == 0:
                return None
            # rows alternate [ ... ]; the list's own ] follows a row's ] directly
            paired = (opens[:m] < closes[:m]) & np.r_[True, closes[:m - 1] < opens[1:m]]
            m = int(np.argmin(paired)) if not paired.all() else m
            if m < k and closes.size > m and (opens.size <= m or closes[m] < opens[m]):
                end, whole = (closes[m - 1] + 1 if m else 0), True   # the list ends
                break
            if m == k:
                end = closes[k - 1] + 1
                after = re.compile(r"\s*,?\s*\]").match(text, start + end)
                whole = after is not None
                break
            if start + size >= len(text):
                return None
            size *= 2
        if m == 0:
            return None
        row = chunk[:end]
        if _ROW_TEXT.search(row):
            return None
        commas = np.flatnonzero(b[:end] == 44)
        inside = np.searchsorted(commas, closes[:m]) - np.searchsorted(commas, opens[:m])
        if np.any(inside != inside[0]):
            return None
        try:
            values = np.array(row.translate({91: None, 93: None}).split(","), dtype=float)
        except ValueError:
            return None
        if values.size != m * (inside[0] + 1) or not np.all(np.isfinite(values)):
            return None
        return values.reshape(m, inside[0] + 1), whole

    try:
        polyline_check(rows, units[0] if units else None)
    except WorkLimitError as exc:
        raise WorkLimitError(f"{path}: {exc}") from None


def _file_dict(curve: NurbsCurve) -> dict:
    d = curve.to_dict()
    order = ("name", "units", "degree", "control_points", "weights", "knots")
    return {k: d[k] for k in order if k in d}


def _toml_text(d: dict) -> str:
    """TOML with one control point per line (tomli_w would put every number on its own)."""
    lines = []
    for key, value in d.items():
        if isinstance(value, str):
            lines.append(tomli_w.dumps({key: value}).strip())
        elif key == "degree":
            lines.append(f"degree = {value}")
        elif key == "control_points":
            rows = "".join(f"    [{', '.join(map(repr, row))}],\n" for row in value)
            lines.append(f"control_points = [\n{rows}]")
        else:
            lines.append(f"{key} = [{', '.join(map(repr, value))}]")
    return "\n".join(lines) + "\n"


def save_path(curve: NurbsCurve, file: str | os.PathLike, *, overwrite: bool = False) -> Path:
    """Write ``curve`` to a JSON, TOML or DXF path file, chosen by the file's ending.

    Parameters
    ----------
    curve : NurbsCurve
        The path.
    file : str or path-like
        ``*.json``, ``*.toml`` or ``*.dxf``. (A G-code program needs a feed: use
        :func:`nurbsmotion.paths.save_gcode`.)
    overwrite : bool
        Replace an existing file; by default an existing file is an error.

    Returns
    -------
    Path
        The written file. Loading it with :func:`load_path` gives back an equal curve
        (exactly for JSON and TOML, to 1e-9 for DXF).

    Raises
    ------
    OutputExistsError
        If the file exists and ``overwrite`` is false.
    PathFileError
        For an unsupported ending.
    """
    path = Path(file)
    suffix = path.suffix.lower()
    if suffix == ".json":
        text = json.dumps(_file_dict(curve), indent=1) + "\n"
        return write_output(path, lambda f: f.write(text), overwrite=overwrite)
    if suffix == ".toml":
        text = _toml_text(_file_dict(curve))
        return write_output(path, lambda f: f.write(text), overwrite=overwrite)
    if suffix == ".dxf":
        from .dxf import save_dxf

        return save_dxf(curve, path, overwrite=overwrite)
    if suffix in _GCODE_SUFFIXES:
        raise PathFileError(
            "a G-code program needs a feed; write it with "
            "nurbsmotion.paths.save_gcode(curve, file, feed=...)",
            source=str(path),
        )
    raise PathFileError(
        f"unknown path file ending {suffix!r}; use .json, .toml or .dxf", source=str(path)
    )


# ---------------------------------------------------------------------- dispatch
_CONTOUR_SELECTOR = re.compile(r"^(?P<file>.+)#(?P<index>\d+)$")


def load_path(file: str | os.PathLike, *, axes: str = "xy", units: str | None = None) -> NurbsCurve:
    """Read one path from a file, dispatching on its ending.

    Parameters
    ----------
    file : str or path-like
        ``*.json`` or ``*.toml`` (the formats of this module), ``*.ngc``, ``*.nc``,
        ``*.gcode``, ``*.tap``, ``*.cnc`` (G-code, see :mod:`nurbsmotion.paths.gcode`) or
        ``*.dxf`` (see :mod:`nurbsmotion.paths.dxf`). A G-code or DXF file may hold several
        separate contours (cut apart by rapid moves, moves of other axes, or gaps); then
        append ``#k`` to the name to choose the k-th (1-based), e.g. ``"butterfly.ngc#2"``.
    axes : str
        The machine's axes that form the path (``"xy"``, ``"xyz"``, ...) of a G-code or DXF
        file; a JSON/TOML path has the axes it lists.
    units : str, optional
        Read the file's numbers in these units (one of :data:`PATH_UNITS`), whatever the
        file says; by default the file's own, or mm with a :class:`PathWarning`.

    Returns
    -------
    NurbsCurve

    Raises
    ------
    PathFileError
        One clear message naming the file (and line or entity) for a missing file, a
        syntax error, a bad field, an invalid curve, or an ambiguous multi-contour file.
    """
    return load_contour(file, axes=axes, units=units).curve


def load_contour(file: str | os.PathLike, *, axes: str = "xy", units: str | None = None,
                 project: bool = False, tool_table: str | os.PathLike | None = None,
                 size_check=None, polyline_check=None) -> Contour:
    """:func:`load_path`, also returning the file's programmed feed (a :class:`Contour`)."""
    spec = os.fspath(file)
    index = None
    match = _CONTOUR_SELECTOR.match(spec)
    if match and not Path(spec).exists():
        spec, index = match.group("file"), int(match.group("index"))
    if polyline_check is not None and Path(spec).suffix.lower() in _GCODE_SUFFIXES:
        _gcode_first_part(spec, index, axes, project, tool_table, polyline_check)
    contours = load_contours(spec, axes=axes, units=units, project=project, tool_table=tool_table,
                             size_check=size_check, polyline_check=polyline_check)
    chosen = _choose_contour([c.curve for c in contours], index, spec)
    return next(c for c in contours if c.curve is chosen)


def _gcode_first_part(spec: str, index: int | None, axes, project: bool, tool_table,
                      polyline_check) -> None:
    """Call ``polyline_check(rows, None)`` for a G-code program, where ``rows(k)`` gives
    the first lines that hold ``k`` pieces of contour ``index`` (None: its only one), read
    by the reader itself (:func:`nurbsmotion.paths.gcode.first_part.read_first_part`: a
    :class:`~nurbsmotion.paths.gcode.first_part.FirstPart`, or None where they are not
    provably a first part of the program), and say which file a refusal is of. Nothing
    is checked where the program, its axes or its tool table cannot be read here: the
    whole program's read names what is wrong."""
    from .gcode.compensation import read_tool_table
    from .gcode.first_part import read_first_part

    path = Path(spec)
    if axes is None or not path.is_file():
        return
    tools = None
    if tool_table is not None:
        try:
            tools = read_tool_table(check_input_file(tool_table), str(path))
        except NurbsmotionError:
            return

    def rows(k: int):
        return read_first_part(path, axes, k, contour=index, project=project, tool_table=tools)

    try:
        polyline_check(rows, None)
    except WorkLimitError as exc:
        raise WorkLimitError(f"{path}: {exc}") from None


def load_contours(file: str | os.PathLike, *, axes: str | None = "xy", units: str | None = None,
                  project: bool = False, tool_table: str | os.PathLike | None = None,
                  size_check=None, polyline_check=None) -> list[Contour]:
    """Every contour of a path file, with its programmed feed (see :func:`load_path`).

    ``axes=None`` reads a G-code or DXF file on every axis it moves (G-code: by a feed or
    a rapid; DXF: XY where every entity is flat, else XYZ); ``project``: a G-code feed
    move of other axes together with ``axes`` is read as its projection on them;
    ``tool_table``: a LinuxCNC tool table (``.tbl``) a G-code program's cutter radius
    compensation takes its tools' diameters from, in the program's units
    (:func:`nurbsmotion.paths.gcode.load_gcode`; ``--tool-table``).

    ``size_check(degree, spans)``, if given, is what the command can do with a path of
    that many knot spans (``run`` and ``bound``:
    :func:`nurbsmotion.planning.check_span_count`): a large JSON or TOML file's spans are
    counted from its text and checked before it is parsed (:data:`SIZE_SCAN_BYTES`), so
    that a path beyond the limit is refused in a fraction of a second, with the file
    named (:class:`~nurbsmotion.errors.WorkLimitError`). ``polyline_check(rows,
    units)``, if given, is called likewise for a large degree-1 JSON or TOML file, whose
    joints may all be corners (``run`` and ``bound``: their count from the vertices,
    :func:`nurbsmotion.study.run_input.load_run_contour`); see :func:`_scan_polyline`."""
    path = Path(file)
    if units is not None and units not in PATH_UNITS:
        raise PathFileError(f"unit {units!r} is not one of {', '.join(PATH_UNITS)}", str(path))
    suffix = path.suffix.lower()
    if tool_table is not None and suffix not in _GCODE_SUFFIXES:
        raise InvalidArgumentError(f"a tool table ({os.fspath(tool_table)}) is read with a G-code "
                                   f"program only, and {path.name} is not one: leave it out")
    if suffix in (".json", ".toml"):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            curve = (_read_json if suffix == ".json" else _read_toml)(
                path, size_check, polyline_check)
        assumed = any(issubclass(w.category, PathWarning) for w in caught)
        for w in caught:  # the override makes the assumption moot
            if units is None or not issubclass(w.category, PathWarning):
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        found = [Contour(curve, None, str(path), None,
                         "assumed: the file has no units field" if assumed else "the file's units field")]
    elif suffix in _GCODE_SUFFIXES:
        from .gcode import GcodeWarning, load_gcode

        with warnings.catch_warnings():
            if units is not None:
                warnings.filterwarnings("ignore", "no G20/G21", GcodeWarning)
            program = load_gcode(path, axes=axes, project=project, tool_table=tool_table)
        found = [Contour(c.curve, None if program.rapids_only else c.feed_limit, f"{path}#{k + 1}",
                         program.axes, program.units_source)
                 for k, c in enumerate(program.contours)]
    elif suffix == ".dxf":
        from .dxf import load_dxf

        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            curves = load_dxf(path, axes=axes)
        assumed = any("declares no unit" in str(w.message) for w in caught)
        for w in caught:
            if units is None or "declares no unit" not in str(w.message):
                warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
        source = "assumed: the drawing declares no unit" if assumed else "the DXF header ($INSUNITS)"
        found = [Contour(c, None, f"{path}#{k + 1}", "XY" if c.n_axes == 2 else "XYZ", source)
                 for k, c in enumerate(curves)]
    else:
        raise PathFileError(
            f"unknown path file ending {suffix!r}; expected one of "
            f"{', '.join(PATH_FILE_SUFFIXES)} or a built-in name ({', '.join(BUILTIN_PATHS)})",
            source=str(path),
        )
    if units is not None:
        found = [Contour(_relabel(c.curve, units), c.feed, c.source, c.axes, "--units") for c in found]
    return found


def _relabel(curve: NurbsCurve, units: str) -> NurbsCurve:
    return NurbsCurve(curve.degree, curve.knots, curve.control_points, curve.weights,
                      name=curve.name, units=units)


def _choose_contour(contours: list[NurbsCurve], index: int | None, source: str) -> NurbsCurve:
    if index is None:
        if len(contours) == 1:
            return contours[0]
        lengths = ", ".join(f"#{i + 1}: {c.length:.6g}" for i, c in enumerate(contours))
        raise PathFileError(
            f"holds {len(contours)} separate contours (lengths {lengths}); choose one by "
            f"appending #k to the file name, e.g. {source}#1",
            source=source,
        )
    if not 1 <= index <= len(contours):
        raise PathFileError(
            f"contour #{index} does not exist; the file holds {len(contours)} (#1 to "
            f"#{len(contours)})",
            source=source,
        )
    return contours[index - 1]


def resolve_path(spec: str, *, axes: str = "xy", units: str | None = None) -> NurbsCurve:
    """A path from a built-in name (``"die-bonder-pi"``, ``"butterfly"``) or a file name.

    This is what the command line calls for its ``PATH`` argument. A built-in name wins
    over a file of the same name only when no such file exists.

    Parameters
    ----------
    spec : str
        Built-in name, or a file name as for :func:`load_path` (``file.ngc#2`` picks a
        contour).

    Raises
    ------
    PathFileError
        If ``spec`` is neither a built-in name nor a readable path file.
    """
    return resolve_contour(spec, axes=axes, units=units).curve


def resolve_contour(spec: str, *, axes: str = "xy", units: str | None = None,
                    project: bool = False, tool_table: str | os.PathLike | None = None,
                    size_check=None, polyline_check=None) -> Contour:
    """:func:`resolve_path`, also returning the file's programmed feed (a :class:`Contour`);
    ``tool_table``, ``size_check`` and ``polyline_check`` as for :func:`load_contours`."""
    if spec in BUILTIN_PATHS and not Path(spec).exists():
        if tool_table is not None:
            raise InvalidArgumentError(f"a tool table ({os.fspath(tool_table)}) is read with a G-code "
                                       f"program only, and {spec} is a built-in path: leave it out")
        curve = builtin_path(spec)
        if units is not None:
            if units not in PATH_UNITS:
                raise PathFileError(f"unit {units!r} is not one of {', '.join(PATH_UNITS)}")
            curve = _relabel(curve, units)
        return Contour(curve, None, spec, None, "--units" if units is not None else "the built-in path")
    if not Path(spec).suffix and not _CONTOUR_SELECTOR.match(spec):
        raise PathFileError(
            f"{spec!r} is neither a built-in path ({', '.join(BUILTIN_PATHS)}) nor a file "
            f"name with an ending ({', '.join(PATH_FILE_SUFFIXES)})"
        )
    return load_contour(spec, axes=axes, units=units, project=project, tool_table=tool_table,
                        size_check=size_check, polyline_check=polyline_check)
