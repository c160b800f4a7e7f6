"""DXF import of XY contours and DXF export of a path, through ezdxf.

Reading
-------
:func:`load_dxf` reads the model space and returns its contours:

- ``SPLINE``: degree, knots, weights and control points as stored. A spline defined by
  fit points only is refused (its curve depends on the CAD system's fitting; re-export it
  with control points). Unclamped (periodic) splines are refused by
  :class:`NurbsCurve`'s validation, wrapped with the entity.
- ``LINE``; ``ARC`` and ``CIRCLE`` as exact rational arcs; ``LWPOLYLINE`` with bulges as
  exact arcs (closing segment included when the polyline is closed).
- Entities must lie in the XY plane (extrusion +Z or -Z; a -Z extrusion mirrors the
  object coordinate system, handled through ezdxf's OCS). Other curve entities
  (``ELLIPSE``, ``POLYLINE``, ``HELIX`` ...) are refused naming their handle; annotation
  (``TEXT``, ``MTEXT``, ``DIMENSION``, ``POINT``, ``HATCH``, ``INSERT`` ...) is ignored with a
  warning that counts it.

DXF entities come in no particular order or direction, so pieces are chained by their
end points: a contour starts with the first unused entity in drawing order and grows at
both ends with any entity that starts or ends where it ends (reversed when needed), to
within ``tolerance`` times the drawing size. Each chain is joined by
:func:`nurbsmotion.joining.join`. The ``$INSUNITS`` header gives the units.

Writing
-------
:func:`save_dxf` writes a path as one rational ``SPLINE`` entity (R2010 DXF); ezdxf
writes floats with their shortest round-trip representation, so reading it back gives
the same curve to rounding (1e-9 is what the tests ask; in practice it is exact).
"""

from __future__ import annotations

import os
import warnings
from collections import Counter
from pathlib import Path

import numpy as np

from .._io import check_input_file, write_output
from ..errors import InvalidCurveError, PathFileError
from ..joining import DEFAULT_JOIN_TOLERANCE, join
from ..nurbs import NurbsCurve, make_line
from .pieces import arc_by_bulge, arc_by_center

__all__ = ["load_dxf", "save_dxf", "DxfWarning"]

_UNITS = {1: "inch", 2: "foot", 4: "mm", 5: "cm", 6: "m", 13: "um"}
_UNITS_CODE = {v: k for k, v in _UNITS.items()}
_IGNORED = {"TEXT", "MTEXT", "DIMENSION", "POINT", "HATCH", "INSERT", "LEADER", "MLEADER",
            "ATTDEF", "SOLID", "VIEWPORT", "IMAGE", "WIPEOUT"}  # fmt: skip


class DxfWarning(UserWarning):
    """Entities of a DXF drawing that were ignored (annotation)."""


def _sniff(path: Path) -> None:
    """Refuse at once a file that does not start like a DXF (ASCII or binary)."""
    with open(path, "rb") as f:
        head = f.read(64)
    if head.startswith(b"AutoCAD Binary DXF"):
        return
    first = head.lstrip(b" \t\r\n").split(b"\n", 1)[0].strip()
    if not first.isdigit():
        raise PathFileError(
            f"not a DXF file: it should start with a group code, got {first[:20]!r}",
            source=str(path),
            line=1,
        )


def _read(path: Path):
    import ezdxf  # lazily: ezdxf takes a while to import

    _sniff(path)
    try:
        return ezdxf.readfile(path)
    except (ezdxf.DXFError, OSError, UnicodeError, ValueError) as exc:
        raise PathFileError(f"cannot read DXF: {exc}", source=str(path)) from None


def _label(entity) -> str:
    return f"{entity.dxftype()} #{entity.dxf.handle}"


def _xy(points, label: str) -> np.ndarray:
    P = np.asarray([tuple(p) for p in points], dtype=float).reshape(-1, 3)
    if np.ptp(P[:, 2]) > 0:
        raise InvalidCurveError(f"{label} is not flat: its points have Z from {P[:, 2].min():g} to {P[:, 2].max():g}")
    return P[:, :2]


def _check_flat_ocs(entity, label: str) -> bool:
    """True when the entity's extrusion is -Z (mirrored OCS); error if not along Z."""
    extrusion = np.asarray(tuple(entity.dxf.get("extrusion", (0.0, 0.0, 1.0))), dtype=float)
    if abs(extrusion[0]) > 1e-12 or abs(extrusion[1]) > 1e-12:
        raise InvalidCurveError(f"{label} is not in the XY plane (extrusion {extrusion.tolist()})")
    return extrusion[2] < 0


def _pieces(entity) -> list[NurbsCurve]:
    """Path pieces of one usable entity, named by type and handle."""
    kind = entity.dxftype()
    label = _label(entity)
    if kind == "LINE":
        start, end = _xy([entity.dxf.start, entity.dxf.end], label)
        return [make_line(start, end, name=label)]
    if kind == "SPLINE":
        if entity.control_point_count() == 0:
            raise InvalidCurveError(
                f"{label} is defined by {entity.fit_point_count()} fit points only; its shape "
                "depends on the CAD system's fitting, so it is not converted: re-export it "
                "with control points (control vertices)"
            )
        weights = list(entity.weights) or None
        return [
            NurbsCurve(
                entity.dxf.degree,
                list(entity.knots),
                _xy(entity.control_points, label),
                weights,
                name=label,
            )
        ]
    if kind in ("ARC", "CIRCLE"):
        mirrored = _check_flat_ocs(entity, label)
        ocs = entity.ocs()
        center = np.array(tuple(ocs.to_wcs(entity.dxf.center)))[:2]
        if kind == "CIRCLE":
            start = end = center + [entity.dxf.radius * (-1.0 if mirrored else 1.0), 0.0]
        else:
            start, end = _xy([entity.start_point, entity.end_point], label)
        return arc_by_center(start, end, center, clockwise=mirrored, name=label)
    if kind == "LWPOLYLINE":
        mirrored = _check_flat_ocs(entity, label)
        ocs = entity.ocs()
        elevation = entity.dxf.elevation
        vertices = [
            (np.array(tuple(ocs.to_wcs((x, y, elevation))))[:2], -b if mirrored else b)
            for x, y, b in entity.get_points("xyb")
        ]
        if entity.closed:
            vertices.append((vertices[0][0], 0.0))
        pieces = []
        for (p, bulge), (q, _) in zip(vertices[:-1], vertices[1:]):
            if np.array_equal(p, q):
                continue  # a repeated vertex is no segment
            if bulge:
                pieces.append(arc_by_bulge(p, q, bulge, name=label))
            else:
                pieces.append(make_line(p, q, name=label))
        if not pieces:
            raise InvalidCurveError(f"{label} has no segment of non-zero length")
        return pieces
    raise InvalidCurveError(
        f"{label}: {kind} entities are not supported (use SPLINE, LINE, ARC, CIRCLE or "
        "LWPOLYLINE)"
    )


def _chain(pieces: list[NurbsCurve], tol: float) -> list[list[NurbsCurve]]:
    """Group pieces into chains whose ends meet, in drawing order where possible."""

    def meets(a, b) -> bool:
        return float(np.linalg.norm(a - b)) <= tol

    remaining = list(pieces)
    chains = []
    while remaining:
        chain = [remaining.pop(0)]
        grown = True
        while grown:
            grown = False
            for i, piece in enumerate(remaining):
                head, tail = chain[0].control_points[0], chain[-1].control_points[-1]
                start, end = piece.control_points[0], piece.control_points[-1]
                if meets(start, tail):
                    chain.append(piece)
                elif meets(end, tail):
                    chain.append(piece.reversed())
                elif meets(end, head):
                    chain.insert(0, piece)
                elif meets(start, head):
                    chain.insert(0, piece.reversed())
                else:
                    continue
                remaining.pop(i)
                grown = True
                break
        chains.append(chain)
    return chains


def load_dxf(
    file: str | os.PathLike, *, tolerance: float = DEFAULT_JOIN_TOLERANCE
) -> list[NurbsCurve]:
    """Read the XY contours of a DXF drawing's model space (see the module docstring).

    Parameters
    ----------
    file : str or path-like
        The drawing.
    tolerance : float
        Largest gap between entity ends that still chains them, relative to the drawing
        size (the largest extent of all control points).

    Returns
    -------
    list of NurbsCurve
        One joined curve per contour, named ``"<file stem>#k"``, in the ``$INSUNITS``
        units (None when the drawing is unitless).

    Raises
    ------
    PathFileError
        If the file is not a readable DXF, has no usable entity, or an entity cannot be
        converted (naming its type and handle).
    """
    path = check_input_file(file)
    doc = _read(path)
    units = _UNITS.get(doc.header.get("$INSUNITS", 0))
    pieces: list[NurbsCurve] = []
    ignored: Counter = Counter()
    for entity in doc.modelspace():
        if entity.dxftype() in _IGNORED:
            ignored[entity.dxftype()] += 1
            continue
        try:
            pieces.extend(_pieces(entity))
        except InvalidCurveError as exc:
            message = str(exc)
            if not message.startswith(_label(entity)):
                message = f"{_label(entity)}: {message}"
            raise PathFileError(message, source=str(path)) from None
    if ignored:
        listing = ", ".join(f"{n} {kind}" for kind, n in sorted(ignored.items()))
        warnings.warn(f"{path}: ignored annotation entities: {listing}", DxfWarning, stacklevel=2)
    if not pieces:
        raise PathFileError(
            "no usable entity in the model space (SPLINE, LINE, ARC, CIRCLE or LWPOLYLINE)",
            source=str(path),
        )
    size = float(np.max(np.ptp(np.vstack([c.control_points for c in pieces]), axis=0)))
    contours = []
    for k, chain in enumerate(_chain(pieces, tolerance * size)):
        try:
            contours.append(join(chain, tolerance=tolerance, name=f"{path.stem}#{k + 1}", units=units))
        except InvalidCurveError as exc:
            raise PathFileError(f"cannot join contour {k + 1}: {exc}", source=str(path)) from None
    return contours


def save_dxf(curve: NurbsCurve, file: str | os.PathLike, *, overwrite: bool = False) -> Path:
    """Write ``curve`` as one rational SPLINE entity in a new R2010 DXF drawing.

    Parameters
    ----------
    curve : NurbsCurve
        A 2-axis (XY) path; written with Z = 0, as :func:`load_dxf` reads XY contours.
    file : str or path-like
        Output drawing.
    overwrite : bool
        Replace an existing file.

    Raises
    ------
    PathFileError
        For a curve that is not 2-axis.
    OutputExistsError
        If the file exists and ``overwrite`` is false.
    """
    import ezdxf

    if curve.n_axes != 2:
        raise PathFileError(f"DXF export writes XY paths; the curve has {curve.n_axes} axes", str(file))
    doc = ezdxf.new("R2010")
    doc.header["$INSUNITS"] = _UNITS_CODE.get(curve.units, 0)  # 0: unitless (ezdxf says m)
    points = np.hstack([curve.control_points, np.zeros((curve.n_control_points, 1))])
    doc.modelspace().add_rational_spline(
        points.tolist(), curve.weights.tolist(), degree=curve.degree, knots=curve.knots.tolist()
    )
    return write_output(file, doc.write, overwrite=overwrite)
