"""DXF import of XY contours and DXF export of a path, through ezdxf.

Reading
-------
:func:`load_dxf` reads the model space and returns its contours:

- ``SPLINE``: degree, knots, weights and control points as stored; a spline defined by
  fit points only as ezdxf constructs it. Repaired as CAD readers do, each repair one
  :class:`DxfWarning` naming the entity: an unclamped (closed, periodic) knot vector is
  rewritten clamped on its domain (the same curve); a knot vector one or two entries
  short of ``n + p + 1`` gets its missing end knots; missing weights are 1
  (:func:`_repaired`).
- ``LINE``; ``ARC`` and ``CIRCLE`` as exact rational arcs; ``LWPOLYLINE`` with bulges as
  exact arcs (closing segment included when the polyline is closed).
- Entities must lie in the XY plane (extrusion +Z or -Z; a -Z extrusion mirrors the
  object coordinate system, handled through ezdxf's OCS). Other curve entities
  (``ELLIPSE``, ``POLYLINE``, ``HELIX`` ...) are refused naming their handle; annotation
  (``TEXT``, ``MTEXT``, ``DIMENSION``, ``POINT``, ``HATCH``, ``INSERT`` ...) is ignored with a
  warning that counts it. A LINE, ARC or CIRCLE of zero length (radius 0) is skipped with
  one warning per kind naming the entities, as CAD programs skip it; a CIRCLE's negative
  radius is read without its sign (AutoCAD and ezdxf do), with a warning.
- A drawing ezdxf's strict reader refuses is read by its recover mode, with a warning
  (:func:`_read`).

DXF entities come in no particular order or direction, so pieces are chained by their
end points: a contour starts with the first unused entity in drawing order and grows at
both ends with the first unused entity that starts or ends where it ends (reversed when
needed), to within ``tolerance`` times the drawing size; the ends are found through a hash
grid of all end points (:func:`_chain_order`), in time linear in the number of pieces.
Each chain is joined by :func:`nurbsmotion.joining.join`. The ``$INSUNITS`` header gives
the units.

Writing
-------
:func:`save_dxf` writes a path as one rational ``SPLINE`` entity (R2010 DXF); ezdxf
writes floats with their shortest round-trip representation, so reading it back gives
the same curve to rounding (1e-9 is what the tests ask; in practice it is exact).
"""

from __future__ import annotations

import itertools
import math
import os
import re
import warnings
from collections import Counter
from pathlib import Path

import numpy as np

from .._runtime.io import check_input_file, write_output
from ..errors import InvalidCurveError, PathFileError, WorkLimitError
from ..joining import DEFAULT_JOIN_TOLERANCE, join
from ..nurbs import NurbsCurve, make_arc, make_line
from .gcode.codes import MAX_COORDINATE
from .pieces import arc_by_bulge

__all__ = ["load_dxf", "save_dxf", "DxfWarning", "MAX_BULGE", "MAX_PIECES"]

_UNITS = {1: "inch", 4: "mm", 5: "cm", 6: "m", 13: "um"}
_UNITS_CODE = {v: k for k, v in _UNITS.items()}
MAX_BULGE = 1e6
"""Largest LWPOLYLINE/POLYLINE bulge read (tan of a quarter of the sweep): 1e6 is a sweep
within 4e-6 rad of a full turn."""


MAX_PIECES = 100_000
"""Most path pieces (lines, arcs, polyline segments) a drawing may hold, from a budget of
about a minute of CPU for reading one. The reading is linear in the pieces (the chaining
through a hash grid of their ends, :func:`_chain_order`); its cost is the curves: each
piece is a :class:`NurbsCurve` built and checked twice (as drawn, then on the machine's
axes and in its chain's direction) and a share of :func:`join`, 0.9 ms of CPU a piece
measured at 10,000 and 100,000 (``benchmarks/size_limits.py``, a 2-core machine at load
10; about 0.65 ms unloaded, by the old reader's ratio), where ezdxf's parsing is 7 % and
the chaining 4 %. A drawing beyond it is refused from its text before ezdxf parses it
(from a first part of it where that holds more: 0.2-0.3 s of CPU for a million). Beyond it, join its segments (a SPLINE, or the
chords' G-code, which reads a million lines in seconds)."""

_PIECE_ENTITY = re.compile(
    rb"\n[ \t]*0[ \t]*\r?\n(VERTEX|LINE|ARC|POLYLINE)[ \t]*\r?\n")


def _check_piece_count(path: Path) -> None:
    """Refuse a drawing of more than :data:`MAX_PIECES` pieces, counted from its text:
    every LINE and ARC entity, and each POLYLINE's VERTEX entities less one (its fewest
    segments; LWPOLYLINE vertices are not counted, so the count is never above the
    drawing's). A binary DXF is left to the reader."""
    with open(path, "rb") as f:
        data = f.read()
    if data.startswith(b"AutoCAD Binary DXF"):
        return
    names = sum(data.count(name) for name in (b"VERTEX", b"LINE", b"ARC"))
    if names <= MAX_PIECES:
        return  # fewer names than the limit (a hundredth of the entity scan's time)
    # The pieces of a first part of the text are at least as many as that part holds (a
    # polyline cut short there counts its vertices in it less one, at most its segments):
    # a part twice the share the names' count gives the limit is scanned first.
    part = len(data) if 4 * (MAX_PIECES + 1) > names else 2 * (MAX_PIECES + 1) * len(data) // names
    pieces = _pieces_in(data[:part])
    if pieces <= MAX_PIECES and part < len(data):
        pieces = _pieces_in(data)
    if pieces > MAX_PIECES:
        raise WorkLimitError(
            f"{path}: the drawing holds at least {pieces:,} path pieces (lines, arcs, "
            f"polyline segments), more than the {MAX_PIECES:,} the DXF reader builds in "
            "about a minute (paths.dxf.MAX_PIECES); join its segments into a SPLINE, or give "
            "the path as G-code")


def _pieces_in(data: bytes) -> int:
    """The path pieces a DXF text holds (see :func:`_check_piece_count`)."""
    counts = Counter(_PIECE_ENTITY.findall(data))
    return counts[b"LINE"] + counts[b"ARC"] + max(counts[b"VERTEX"] - counts[b"POLYLINE"], 0)


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
    """The drawing, read by ezdxf's strict reader; a drawing it refuses is read again by
    ezdxf's recover mode (``ezdxf.recover.readfile``: group codes out of order, missing
    sections, a wrong encoding, then its audit), as CAD programs open such files, with one
    :class:`DxfWarning` saying so. Refused when recover fails too."""
    import ezdxf  # lazily: ezdxf takes a while to import

    errors = (ezdxf.DXFError, UnicodeError, ValueError, TypeError, KeyError, IndexError,
              AttributeError, EOFError, ArithmeticError, RuntimeError)
    _sniff(path)
    try:
        return ezdxf.readfile(path)
    except OSError as exc:
        raise PathFileError(f"cannot read DXF: {_one_line(exc)}", source=str(path)) from None
    except StopIteration:  # ezdxf's tag reader ran out inside a section
        strict = "the file ends inside a section (cut short?)"
    except errors as exc:
        strict = _one_line(exc)
    from ezdxf import recover

    refused = PathFileError(f"cannot read DXF: {strict} (open the drawing in a CAD program and "
                            "save it again as DXF)", source=str(path))
    try:
        doc, auditor = recover.readfile(path)
    except (StopIteration, OSError, *errors):
        raise refused from None
    if len(doc.modelspace()) == 0:  # a file cut short inside its entities: nothing recovered
        raise refused
    fixes = len(auditor.fixes)
    _warn(f"{path}: the strict DXF reader refused the drawing ({strict}); read by ezdxf's recover "
          f"mode, which repaired it ({fixes} audit fix{'' if fixes == 1 else 'es'}): check the "
          "contours, or save the drawing again from a CAD program")
    return doc


def _one_line(exc: BaseException) -> str:
    """An exception's text on one line (ezdxf's messages may span several)."""
    text = " ".join(str(exc).split())
    return text or type(exc).__name__


def _label(entity) -> str:
    return f"{entity.dxftype()} #{entity.dxf.handle}"


def _wcs(points) -> np.ndarray:
    if isinstance(points, np.ndarray):
        P = points.astype(float).reshape(-1, 3)
    else:
        P = np.asarray([tuple(p) for p in points], dtype=float).reshape(-1, 3)
    if not np.all(np.isfinite(P)) or np.max(np.abs(P), initial=0.0) > MAX_COORDINATE:
        bad = P[~np.all(np.isfinite(P) & (np.abs(P) <= MAX_COORDINATE), axis=1)][0]
        raise InvalidCurveError(f"a point {bad.tolist()} is not finite or beyond the largest "
                                f"coordinate read, {MAX_COORDINATE:g} (MAX_COORDINATE)")
    return P


def _in_ocs(curve: NurbsCurve, ocs, elevation: float) -> NurbsCurve:
    """A curve drawn in an entity's object coordinate system ``ocs`` (ezdxf's ``OCS``; x,
    y at ``elevation``) mapped to world coordinates: an affine map, exact on the control
    points, and the identity where the extrusion is +Z (ezdxf's ``OCS.transform`` false)."""
    P = np.column_stack([curve.control_points, np.full(curve.n_control_points, float(elevation))])
    W = _wcs(P if not ocs.transform else ocs.points_to_wcs(P.tolist()))
    return NurbsCurve(curve.degree, curve.knots, W, curve.weights, name=curve.name)


def _number(entity, value, what: str) -> float:
    v = float(value)
    if not math.isfinite(v):
        raise InvalidCurveError(f"{_label(entity)}: {what} {v!r} is not finite")
    return v


def _bulge_pieces(entity, vertices: list, closed: bool, elevation: float) -> list[NurbsCurve]:
    """Lines and arcs of a 2-D polyline: ``vertices`` are (x, y, bulge) in the OCS."""
    label = _label(entity)
    pts = [(np.array([_number(entity, x, "vertex x"), _number(entity, y, "vertex y")]),
            _number(entity, b, "bulge")) for x, y, b in vertices]
    if closed and pts:
        pts.append((pts[0][0], 0.0))
    ocs = entity.ocs()
    z = float(elevation)
    pieces = []
    for (p, bulge), (q, _) in zip(pts[:-1], pts[1:]):
        if np.array_equal(p, q):
            continue  # a repeated vertex is no segment
        if abs(bulge) > MAX_BULGE:
            raise InvalidCurveError(f"{label}: bulge {bulge:g} is beyond the largest read, "
                                    f"{MAX_BULGE:g} (MAX_BULGE; the arc's radius would be "
                                    f"{np.hypot(*(q - p)) * (1 + bulge * bulge) / (4 * abs(bulge)):.3g})")
        if bulge:
            pieces.append(_in_ocs(arc_by_bulge(p, q, bulge, name=label), ocs, z))
        elif not ocs.transform:  # in the WCS: the line drawn there at once (the same curve)
            pieces.append(make_line(*_wcs(np.array([[*p, z], [*q, z]])), name=label))
        else:
            pieces.append(_in_ocs(make_line(p, q, name=label), ocs, z))
    return pieces


def _unclamped_to_clamped(degree: int, knots, points: np.ndarray, weights) -> tuple:
    """A B-spline with any knot vector (a closed or periodic DXF spline), restricted to
    its domain ``[t_p, t_(n)]`` and written with clamped knots: an exact change of basis
    (the homogeneous spline interpolated at the Greville abscissae of the new knots)."""
    from scipy.interpolate import BSpline, make_interp_spline

    t = np.asarray(knots, dtype=float)
    p = degree
    n = len(points)
    w = np.ones(n) if weights is None or len(weights) == 0 else np.asarray(weights, dtype=float)
    a, b = t[p], t[n]
    inner = t[p + 1: n]
    new = np.concatenate([[a] * (p + 1), inner, [b] * (p + 1)])
    m = len(new) - p - 1
    greville = np.clip(np.array([np.mean(new[i + 1: i + p + 1]) for i in range(m)]), a, b)
    H = BSpline(t, np.column_stack([points * w[:, None], w]), p)(greville)
    fit = make_interp_spline(greville, H, k=p, t=new)
    return new, fit.c[:, :-1] / fit.c[:, -1:], fit.c[:, -1]


def _multiplicity(values: np.ndarray) -> int:
    """How many entries at the start of ``values`` equal the first."""
    return int(np.argmax(values != values[0])) if np.any(values != values[0]) else len(values)


def _repaired(label: str, degree: int, knots: np.ndarray, n: int, weights) -> tuple:
    """A SPLINE's knots and weights as CAD readers take them where the file is short of
    them, one :class:`DxfWarning` naming the entity per repair:

    - ``n + p - 1`` knots (OpenNURBS's convention, which leaves out the two end knots that
      no basis function of the curve's domain uses): the first and last knot repeated;
    - ``n + p`` knots: the end knot that the other end shows is missing (an end with ``p``
      equal knots where the other has ``p + 1``, or the end of a uniform vector) added;
      the end knots do not change the curve on its domain ``[t_p, t_n]``;
    - fewer weights than control points: the others 1 (ezdxf's weight of a spline that
      gives none).
    """
    p, k = degree, np.asarray(knots, dtype=float)
    expected = n + p + 1
    if n > p and len(k) in (expected - 1, expected - 2) and len(k) >= 2 and np.all(np.diff(k) >= 0):
        head, tail = _multiplicity(k), _multiplicity(k[::-1])
        steps = np.diff(k)
        uniform = bool(np.allclose(steps, steps[0], rtol=1e-12, atol=0.0)) and steps[0] > 0
        if len(k) == expected - 2:
            k, where = np.concatenate([k[:1], k, k[-1:]]), "the first and last knot repeated"
        elif head == p and tail != p:
            k, where = np.concatenate([k[:1], k]), "the first knot repeated"
        elif tail == p and head != p:
            k, where = np.concatenate([k, k[-1:]]), "the last knot repeated"
        elif uniform:
            k, where = np.concatenate([k, [k[-1] + steps[0]]]), "a last knot added at the same spacing"
        else:
            raise InvalidCurveError(f"{label}: knot vector has {len(knots)} entries, expected {expected} "
                                    f"= n + p + 1 ({n} control points, degree {p}), and which end "
                                    "lacks one cannot be told")
        _warn(f"{label}: knot vector has {len(knots)} entries, expected {expected} = n + p + 1 "
              f"({n} control points, degree {p}); {where}, as CAD readers do")
    if weights is not None and 0 < len(weights) < n:
        _warn(f"{label}: {len(weights)} weights for {n} control points; the other "
              f"{n - len(weights)} read as 1")
        weights = np.concatenate([weights, np.ones(n - len(weights))])
    return k, weights


def _pieces(entity) -> list[NurbsCurve]:
    """Path pieces of one entity in world coordinates (3 columns), named by type and
    handle; an empty list for a degenerate entity of zero length."""
    kind = entity.dxftype()
    label = _label(entity)
    if kind == "LINE":
        start, end = _wcs([entity.dxf.start, entity.dxf.end])
        return [] if np.array_equal(start, end) else [make_line(start, end, name=label)]
    if kind == "SPLINE":
        if entity.control_point_count() > 0:  # as stored
            degree = int(entity.dxf.degree)
            knots = np.asarray(list(entity.knots), dtype=float)
            points = _wcs(entity.control_points)
            weights = np.asarray(list(entity.weights), dtype=float) if len(entity.weights) else None
        else:  # fit points only: ezdxf's own construction of the curve through them
            fit = _wcs(entity.fit_points)  # checked first: NaN gave "Singular matrix"
            if np.ptp(fit, axis=0).max(initial=0.0) == 0.0:  # "list index out of range"
                return []
            tool = entity.construction_tool()
            degree = int(tool.degree)
            knots = np.asarray(tool.knots(), dtype=float)
            points = _wcs(tool.control_points)
            weights = np.asarray(tool.weights(), dtype=float) if tool.is_rational else None
        if weights is not None and not (np.all(np.isfinite(weights)) and np.all(weights > 0)):
            raise InvalidCurveError(f"{label}: weights must be finite and > 0")
        if not np.all(np.isfinite(knots)):
            raise InvalidCurveError(f"{label}: knots must be finite")
        knots, weights = _repaired(label, degree, knots, len(points), weights)
        if len(points) > degree and np.all(np.diff(knots) >= 0) and len(knots) == len(points) + degree + 1 \
                and not (np.all(knots[:degree + 1] == knots[0]) and np.all(knots[-degree - 1:] == knots[-1])):
            knots, points, weights = _unclamped_to_clamped(degree, knots, points, weights)
            _warn(f"{label}: unclamped knot vector (a closed or periodic spline); read on its "
                  f"domain [{knots[0]:.6g}, {knots[-1]:.6g}] as the same curve with clamped knots")
        if np.ptp(points, axis=0).max(initial=0.0) == 0.0:
            return []
        return [NurbsCurve(degree, knots, points, weights, name=label)]
    if kind in ("ARC", "CIRCLE"):
        radius = _number(entity, entity.dxf.radius, "radius")
        if radius == 0.0:  # a point, not a path: skipped as CAD programs skip it
            return []
        if kind == "CIRCLE" and radius < 0.0:
            # AutoCAD ignores a CIRCLE's sign, and so does ezdxf's evaluation (Circle.vertices)
            _warn(f"{label}: radius {radius:g} read as {-radius:g} (CAD programs ignore the sign "
                  "of a circle's radius)")
            radius = -radius
        if not 0 < radius <= MAX_COORDINATE:
            raise InvalidCurveError(f"{label}: radius {radius:g} must be > 0 and at most "
                                    f"{MAX_COORDINATE:g}: correct or delete the entity in the drawing")
        center = np.array([_number(entity, v, "centre") for v in entity.dxf.center])
        if kind == "CIRCLE":
            a0, a1 = 0.0, 2 * math.pi
        else:
            a0 = math.radians(_number(entity, entity.dxf.start_angle, "start angle")) % (2 * math.pi)
            a1 = math.radians(_number(entity, entity.dxf.end_angle, "end angle")) % (2 * math.pi)
            if a1 <= a0:
                a1 += 2 * math.pi
        return [_in_ocs(make_arc(center[:2], radius, a0, a1, name=label), entity.ocs(), center[2])]
    if kind == "ELLIPSE":
        # exact rational form: the unit-circle arc over the ellipse's parameter range,
        # mapped by the affine map (x, y) -> centre + x major + y minor
        from ezdxf.entities.ellipse import MIN_RATIO

        e = entity.construction_tool()
        center, major, minor = (np.array(tuple(v), dtype=float) for v in (e.center, e.major_axis, e.minor_axis))
        t0, t1 = float(e.start_param), float(e.end_param)
        if not (abs(e.ratio) >= MIN_RATIO):
            # ezdxf's own rule (is_valid_ratio; its audit "fixes" such a ratio to 1e-10, a
            # needle whose two ends turn within 1e-10 of the major axis): ratio 0 is no
            # ellipse but its major axis traversed there and back.
            raise InvalidCurveError(
                f"{label}: axis ratio {e.ratio!r} is below the smallest valid one, {MIN_RATIO:g} "
                f"(ezdxf's check): a flat ellipse is its major axis {major.tolist()} traversed "
                "there and back; draw it as LINE entities")
        if not all(map(math.isfinite, (t0, t1))) or np.linalg.norm(major) == 0:
            raise InvalidCurveError(f"{label}: degenerate ellipse (major axis {major.tolist()}, "
                                    f"ratio {e.ratio!r})")
        if t1 <= t0:
            t1 += 2 * math.pi
        unit = make_arc([0.0, 0.0], 1.0, t0, t1, name=label)
        P = _wcs(center + unit.control_points[:, :1] * major + unit.control_points[:, 1:] * minor)
        return [NurbsCurve(2, unit.knots, P, unit.weights, name=label)]
    if kind == "LWPOLYLINE":
        return _bulge_pieces(entity, list(entity.get_points("xyb")), entity.closed, entity.dxf.elevation)
    if kind == "POLYLINE":
        if entity.is_2d_polyline:
            verts = [(v.dxf.location[0], v.dxf.location[1], v.dxf.get("bulge", 0.0)) for v in entity.vertices]
            return _bulge_pieces(entity, verts, entity.is_closed, entity.dxf.elevation[2])
        if entity.is_3d_polyline:
            P = _wcs(entity.points())
            if entity.is_closed:
                P = np.vstack([P, P[:1]])
            keep = np.concatenate([[True], np.any(np.diff(P, axis=0) != 0, axis=1)])
            P = P[keep]
            return [make_line(p, q, name=label) for p, q in zip(P[:-1], P[1:])]
    return None  # not a path entity


def _chain_order(ends: np.ndarray, tol: float) -> list[list[tuple[int, bool]]]:
    """Group pieces into chains whose ends meet, in drawing order where possible: each
    chain starts with the first unused piece, grows at its tail, then at its head, with
    the first unused piece (lowest index) that starts or ends within ``tol`` of it
    (Euclidean distance), reversed when needed (at the tail a piece whose start is near
    is taken forward, at the head one whose end is near).

    The candidates come from :class:`_EndGrid`, a hash grid of the pieces' end points, so
    chaining takes time linear in the number of pieces where a bounded number of ends meet
    near any point (the earlier search of every end at every step took quadratic time,
    which capped drawings at 20,000 pieces); the distances are the same expression as
    that search's, so the same pieces join, in the same order and direction.

    Parameters
    ----------
    ends : ndarray, shape (2 n_pieces, n_axes)
        Row ``2 i`` the start of piece i, row ``2 i + 1`` its end [path units].
    tol : float
        Largest gap that joins two ends [path units].

    Returns
    -------
    list of list of (int, bool)
        Per chain, its pieces from head to tail: (index, forward).
    """
    n = len(ends) // 2
    grid = _EndGrid(ends, tol)
    used = [False] * n
    chains = []
    for first in range(n):
        if used[first]:
            continue
        used[first] = True
        tail: list[tuple[int, bool]] = [(first, True)]
        head: list[tuple[int, bool]] = []  # grown outwards: reversed at the end
        for at_tail in (True, False):
            row = 2 * first + 1 if at_tail else 2 * first  # the chain's free end
            while True:
                near = grid.near(row, used)
                if not near:
                    break
                i = min(near) >> 1
                used[i] = True
                # at the tail a piece runs forward from a near start; at the head it runs
                # forward into a near end
                forward = (2 * i if at_tail else 2 * i + 1) in near
                if at_tail:
                    tail.append((i, forward))
                    row = 2 * i + 1 if forward else 2 * i
                else:
                    head.append((i, forward))
                    row = 2 * i if forward else 2 * i + 1
        chains.append(head[::-1] + tail)
    return chains


def _piece_ends(pieces: list[NurbsCurve], keep: int) -> np.ndarray:
    """The first ``keep`` coordinates of each piece's start (row ``2 i``) and end (row
    ``2 i + 1``), shape (2 len(pieces), keep)."""
    ends = np.empty((2 * len(pieces), keep))
    ends[0::2] = [c.control_points[0, :keep] for c in pieces]
    ends[1::2] = [c.control_points[-1, :keep] for c in pieces]
    return ends


def _chain(pieces: list[NurbsCurve], tol: float) -> list[list[NurbsCurve]]:
    """The pieces grouped into chains by :func:`_chain_order`, each reversed where it runs
    backwards."""
    if not pieces:
        return []
    return [[pieces[i] if forward else pieces[i].reversed() for i, forward in chain]
            for chain in _chain_order(_piece_ends(pieces, pieces[0].n_axes), tol)]


class _EndGrid:
    """The pieces' end points, hashed by the cell of a grid of spacing ``2 tol`` (at
    least 2**-30 of their extent, so that ``tol = 0`` still has cells) that holds them.

    Every end within ``tol`` of a point lies in the point's cell or a neighbouring one
    (each coordinate differs by at most ``tol``, half a cell, also after rounding), so
    :meth:`near` looks at the ``3**n_axes`` cells around it. A tolerance of half the
    extent or more (or not finite) puts every end in one cell.

    Parameters
    ----------
    ends : ndarray, shape (2 n_pieces, n_axes)
        Row ``2 i`` the start of piece i, row ``2 i + 1`` its end [path units].
    tol : float
        Largest distance of a near end [path units].
    """

    def __init__(self, ends: np.ndarray, tol: float):
        self.ends = ends
        self.tol = tol
        extent = float(np.max(np.ptp(ends, axis=0)))
        if 2 * tol < extent:  # false for a NaN or infinite tolerance too
            spacing = max(2 * tol, extent * 2.0**-30)
            # float cells: exact neighbours below 2**53, one cell per value beyond
            cells = list(map(tuple, np.floor(ends / spacing).tolist()))
            self.offsets = list(itertools.product((-1.0, 0.0, 1.0), repeat=ends.shape[1]))
        else:
            cells = [()] * len(ends)
            self.offsets = [()]
        self.cells = cells
        self.rows: dict[tuple, list[int]] = {}
        for row, cell in enumerate(cells):
            self.rows.setdefault(cell, []).append(row)

    def near(self, row: int, used: list[bool]) -> set[int]:
        """Rows of the ends of unused pieces within ``tol`` of row ``row``'s point (the
        norm as ``np.linalg.norm`` computes it, compared with ``<=``); rows of used
        pieces are dropped from their cells on the way."""
        cell = self.cells[row]
        candidates = []
        for offset in self.offsets:
            key = tuple(c + o for c, o in zip(cell, offset))
            rows = self.rows.get(key)
            if rows is None:
                continue
            free = [r for r in rows if not used[r >> 1]]
            if len(free) < len(rows):
                if free:
                    self.rows[key] = free
                else:
                    del self.rows[key]
            candidates += free
        if not candidates:
            return set()
        distance = np.linalg.norm(self.ends[candidates] - self.ends[row], axis=1)
        return {r for r, near in zip(candidates, (distance <= self.tol).tolist()) if near}


def load_dxf(
    file: str | os.PathLike, *, tolerance: float = DEFAULT_JOIN_TOLERANCE, axes: str | None = "xy"
) -> list[NurbsCurve]:
    """Read the contours of a DXF drawing's model space (see the module docstring).

    Parameters
    ----------
    file : str or path-like
        The drawing.
    tolerance : float
        Largest gap between entity ends that still chains them, relative to the drawing
        size (the largest extent of all control points).
    axes : {"xy", "xyz"}
        The machine's axes: ``"xy"`` reads flat entities (each at a constant Z) as 2-axis
        paths; ``"xyz"`` reads 3-D paths; None: ``"xy"`` where every entity is flat, else
        ``"xyz"`` (what ``nurbsmotion contours`` lists).

    Returns
    -------
    list of NurbsCurve
        One joined curve per contour, named ``"<file stem>#k"``, in the ``$INSUNITS``
        units (mm, with a :class:`DxfWarning`, when the drawing declares none).

    Raises
    ------
    PathFileError
        One line naming the file (and the entity's type and handle): not a readable DXF,
        no path entity, an entity that cannot be converted or a bad value in it.
    """
    path = check_input_file(file)
    _check_piece_count(path)  # before ezdxf is imported and parses it
    import ezdxf

    auto = axes is None
    axes = "xyz" if auto else str(axes).lower()
    if axes not in ("xy", "xyz"):
        raise PathFileError(f"DXF paths have the axes xy or xyz, not {axes!r}", str(path))
    doc = _read(path)
    code = doc.header.get("$INSUNITS", 0)
    if code in (0, None):
        units = "mm"
        _warn(f"{path}: the drawing declares no unit ($INSUNITS {code}); reading millimetres "
              "(give --units to choose)")
    elif code in _UNITS:
        units = _UNITS[code]
    else:
        raise PathFileError(f"drawing unit $INSUNITS = {code!r} is not one of the units read "
                            f"({', '.join(f'{k} = {v}' for k, v in sorted(_UNITS.items()))}); give "
                            "--units to read its numbers in another unit", str(path))
    pieces: list[NurbsCurve] = []
    flat = True  # every piece at a constant Z
    skipped: Counter = Counter()
    degenerate: dict[str, list[str]] = {}  # kind -> handles of entities of zero length
    for entity in doc.modelspace():
        try:
            found = _pieces(entity)
            if found is None:
                skipped[entity.dxftype()] += 1
                continue
            if not found:
                degenerate.setdefault(entity.dxftype(), []).append(f"#{entity.dxf.handle}")
            for piece in found:
                z = piece.control_points[:, 2]
                flat = flat and not np.ptp(z) > 1e-12 * max(1.0, np.max(np.abs(z)))
                if axes == "xy" and not flat:
                    raise InvalidCurveError(
                        f"{_label(entity)} is not flat: Z runs from {z.min():g} to {z.max():g}; a "
                        "machine with a Z axis (xyz) can read it")
                pieces.append(piece)  # cut to the machine's axes once chained (_final)
        except (InvalidCurveError, ValueError, TypeError, AttributeError, IndexError, KeyError,
                ZeroDivisionError, OverflowError, ezdxf.DXFError) as exc:
            message = _one_line(exc)
            if not message.startswith(_label(entity)):
                message = f"{_label(entity)}: {message}"
            raise PathFileError(message, source=str(path)) from None
    for kind, n in sorted(skipped.items()):
        _warn(f"{path}: {n} {kind} entit{'y' if n == 1 else 'ies'} skipped (not a path)")
    if not pieces:
        zero = "".join(f"; {len(h)} {kind} of zero length ({_handles(h)})" for kind, h in sorted(degenerate.items()))
        raise PathFileError(
            "no path entity in the model space (LINE, ARC, CIRCLE, ELLIPSE, SPLINE, LWPOLYLINE, "
            f"POLYLINE){zero}", source=str(path))
    for kind, handles in sorted(degenerate.items()):
        n = len(handles)
        _warn(f"{path}: {n} {kind} entit{'y' if n == 1 else 'ies'} of zero length skipped "
              f"({_handles(handles)}), as CAD programs skip them")
    keep = 2 if axes == "xy" or (auto and flat) else 3
    ends = _piece_ends(pieces, keep)
    size = float(np.max(np.ptp(np.vstack([c.control_points[:, :keep] for c in pieces]), axis=0)))
    contours = []
    for k, chain in enumerate(_chain_order(ends, tolerance * size)):
        chain = [_final(pieces[i], keep, forward, path) for i, forward in chain]
        try:
            contours.append(join(chain, tolerance=tolerance, name=f"{path.stem}#{k + 1}", units=units))
        except InvalidCurveError as exc:
            raise PathFileError(f"cannot join contour {k + 1}: {_one_line(exc)}", source=str(path)) from None
    return contours


def _final(piece: NurbsCurve, keep: int, forward: bool, path: Path) -> NurbsCurve:
    """A piece as built (3 coordinates) on the machine's first ``keep`` axes, reversed
    unless ``forward``: one curve, equal to slicing and then :meth:`NurbsCurve.reversed`
    (the knots are already normalised to [0, 1], which the constructor keeps)."""
    if keep == piece.n_axes and forward:
        return piece
    step = 1 if forward else -1
    knots = piece.knots if forward else 1.0 - piece.knots[::-1]
    try:
        return NurbsCurve(piece.degree, knots, piece.control_points[::step, :keep],
                          piece.weights[::step], name=piece.name)
    except InvalidCurveError as exc:  # a piece flat to 1e-12 of its Z but not in X, Y
        message = _one_line(exc)
        if not message.startswith(str(piece.name)):
            message = f"{piece.name}: {message}"
        raise PathFileError(message, source=str(path)) from None


def _handles(handles: list[str], shown: int = 3) -> str:
    """The first ``shown`` entity handles, and how many more."""
    more = len(handles) - shown
    return ", ".join(handles[:shown]) + (f" and {more} more" if more > 0 else "")


def _warn(message: str) -> None:
    warnings.warn(message, DxfWarning, stacklevel=3)


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
