"""NURBS curves: the value object every other stage of nurbsmotion reads.

A :class:`NurbsCurve` knows nothing of time, feeds or servos. It evaluates points and exact
rational derivatives, and (through :mod:`nurbsmotion.geometry`) arc length, tangent,
curvature and sharp corners.

Conventions
-----------
- Knot vectors are *clamped* (the first and the last ``p + 1`` knots are equal); unclamped
  (periodic, floating) knot vectors are rejected with :class:`InvalidCurveError`, since a
  toolpath must start and end on its end control points.
- Any non-decreasing knot values are accepted, and the domain is normalised to ``[0, 1]``:
  the stored :attr:`NurbsCurve.knots` are ``(t - t[0]) / (t[-1] - t[0])``, and every method
  takes the normalised parameter ``u``. The original end values are kept in
  :attr:`NurbsCurve.domain`.
- Interior knots may repeat up to the degree ``p``. Multiplicity ``p`` makes the curve only
  C0 there: a possible *sharp corner*. Derivatives at such a knot are one-sided, from the
  right by default (the span the motion moves into, docs/model.md#interpolation), from the left with
  ``side="left"``.

- Limits of double precision are refused at construction with the limit in the message:
  a degree above :data:`MAX_DEGREE`, coordinates or weights beyond
  :data:`MAX_MAGNITUDE`, coordinates more than :data:`MAX_OFFSET_RATIO` times the curve's
  size from the origin (they could not be computed to 1e-9 of that size), weights whose
  ratio exceeds it, units outside :data:`PATH_UNITS`; booleans and strings are never
  numbers.

Glossary
--------
p : degree; n : number of control points; u : curve parameter in [0, 1];
P : control points ``(n, n_axes)``; w : weights ``(n,)``;
C(u) : curve point; C^(k)(u) : k-th derivative with respect to u.

References
----------
Piegl & Tiller, *The NURBS Book*, 2nd ed., Springer 1997: A4.2 (rational derivatives),
A7.1 (circular arcs).

Why one module of about 1,000 lines: most of it is :class:`NurbsCurve` (about 600),
one value object whose construction checks (knots, weights, the limits of double
precision), evaluation, derivatives and operations (power form, arc length, corners,
reverse, scale) share its private state; the ``make_*`` factories beside it are short.
Splitting it would split the class.
"""

from __future__ import annotations

import json
import math
from importlib import resources
from typing import Any

import numpy as np

from .errors import InvalidArgumentError, InvalidCurveError
from .limits import PATH_UNITS

__all__ = [
    "NurbsCurve",
    "make_line",
    "make_polyline",
    "make_arc",
    "make_circle",
    "make_die_bonder_pi",
    "make_butterfly",
    "builtin_path",
    "BUILTIN_PATHS",
    "MAX_CONTROL_POINTS",
]

MAX_ORDER = 3
"""Highest derivative order :meth:`NurbsCurve.__call__` evaluates (3 is jerk)."""


MAX_DEGREE = 32
"""Highest degree a curve may have. The check that C' never vanishes (at construction)
finds the roots of a degree 2p - 2 polynomial per span from its companion matrix; beyond
a degree-62 polynomial those roots are no longer reliable in double precision, and CAD
systems stay far below (degree 3 to 11)."""

MIN_KNOT_SPAN = float(np.finfo(float).eps)
"""Shortest nonzero knot span, as a fraction of the knot domain (2.2e-16): the spacing of
doubles just below the normalised domain's end, so a shorter span holds no parameter there;
and with coordinates within :data:`MAX_MAGNITUDE` and degree within :data:`MAX_DEGREE`
it keeps the derivatives up to :data:`MAX_ORDER`, their squares and ``|C'|^3`` finite
(a span of 1e-300 overflowed them: NumPy warnings and an arc-length table that never
converged, issue 37). A curve with a shorter span is refused naming it."""

RELATIVE_ACCURACY = 1e-9
"""Relative accuracy the geometry promises (arc length, inverse, points)."""

MAX_OFFSET_RATIO = RELATIVE_ACCURACY / np.finfo(float).eps
"""Largest ratio of a coordinate's magnitude to the curve's extent (about 4.5e6): a
coordinate carries a rounding error of eps*|x|, which must stay below 1e-9 of the curve's
size. A 100 mm part may lie up to 450 m from the origin; a part offset by 1e15 is refused.
The same bound limits max(weight) / min(weight), since a control point's share of the
rational sum is computed to eps times that ratio."""

MAX_MAGNITUDE = 1e50
"""Largest magnitude of a coordinate [path units] or weight (and smallest weight is its
inverse): keeps w*P, |C'|^3 (curvature) and the servo's squares finite in double
precision, whatever the knot spacing."""

MAX_CONTROL_POINTS = 5_000_000
"""Most control points a curve may have (so at most that many knot spans): a
1,000,000-line CAM program joined into one path has about 2,000,000. A curve is
refused beyond it when it is built, and a path file when it is read, before its points
are converted or checked: the arc-length tables and the zero-speed check grow with the
spans (a million control points took 106 s and 3.4 GB before the planner refused them;
within this limit, :func:`nurbsmotion.planning.check_path_size` refuses from the knots
alone a path whose planner grid would not fit)."""


def _as_float_array(value: Any, name: str, ndim: int) -> np.ndarray:
    """``value`` as a float array; booleans and strings are never numbers."""
    try:
        raw = np.asarray(value)
        # numpy turns True into 1 in a list of numbers: look at the Python values too.
        if raw.dtype.kind in "bUSV" or _holds_non_number(value):
            raise TypeError("not a number")
        arr = np.array(raw, dtype=float)
    except OverflowError:
        raise InvalidCurveError(
            f"{name} holds a number too large for double precision (limit "
            f"{MAX_MAGNITUDE:g}): {value!r:.80}") from None
    except (TypeError, ValueError) as exc:
        raise InvalidCurveError(f"{name} must be numeric, got {value!r:.80}") from exc
    if arr.ndim != ndim:
        shape = "(n,)" if ndim == 1 else "(n, n_axes)"
        raise InvalidCurveError(f"{name} must have shape {shape}, got shape {arr.shape}")
    return arr


_NOT_NUMBERS = (bool, np.bool_, str, bytes, type(None))


def _holds_non_number(value: Any) -> bool:
    """Whether ``value`` (a number, an array or nested lists) holds a boolean or a string."""
    if isinstance(value, np.ndarray) and value.dtype.kind != "O":
        return value.dtype.kind in "bUSV"
    try:
        items = np.asarray(value, dtype=object)
    except ValueError:  # ragged: refused when converted
        return False
    return any(issubclass(t, _NOT_NUMBERS) for t in set(map(type, items.flat)))


def _check_magnitudes(P: np.ndarray, w: np.ndarray) -> float:
    """Refuse coordinates and weights beyond what double precision computes to 1e-9;
    return the control points' extent (their largest range over one axis) [path units]."""
    big = np.abs(P) > MAX_MAGNITUDE
    if np.any(big):
        i = _first_bad(np.any(big, axis=1))
        raise InvalidCurveError(
            f"control point {i} = {P[i].tolist()} exceeds the largest coordinate magnitude "
            f"{MAX_MAGNITUDE:g} path units")
    bad = (w > MAX_MAGNITUDE) | (w < 1.0 / MAX_MAGNITUDE)
    if np.any(bad):
        i = _first_bad(bad)
        raise InvalidCurveError(
            f"weight {i} is {w[i]:g}; weights must lie in [{1 / MAX_MAGNITUDE:g}, "
            f"{MAX_MAGNITUDE:g}]")
    ratio = float(w.max() / w.min())
    if ratio > MAX_OFFSET_RATIO:
        raise InvalidCurveError(
            f"weights range from {w.min():g} to {w.max():g} (ratio {ratio:.3g}); a ratio "
            f"above {MAX_OFFSET_RATIO:.3g} cannot be computed to {RELATIVE_ACCURACY:g} "
            "relative accuracy in double precision")
    extent = point_extent(P)
    magnitude = float(np.max(np.abs(P)))
    if extent > 0 and magnitude > MAX_OFFSET_RATIO * extent:
        raise InvalidCurveError(
            f"coordinates reach {magnitude:.6g} but the curve spans only {extent:.6g} path "
            f"units (ratio {magnitude / extent:.3g}); beyond {MAX_OFFSET_RATIO:.3g} times "
            f"its size a curve cannot be computed to {RELATIVE_ACCURACY:g} relative accuracy "
            "in double precision: move it nearer the origin")
    return extent


def point_extent(points: np.ndarray) -> float:
    """The largest range of ``points`` (shape (n, n_axes)) over one axis [their unit]:
    ``max(np.ptp(points, axis=0))``, exactly, column by column (a reduction along the
    first axis of an (n, 2) array is ten times slower: a million-point path's checks)."""
    return max(float(np.max(points[:, j]) - np.min(points[:, j]))
               for j in range(points.shape[1]))


def _first_bad(mask: np.ndarray) -> int:
    return int(np.flatnonzero(mask)[0])


def _check_count(control_points) -> None:
    """Refuse more than :data:`MAX_CONTROL_POINTS` control points before converting them."""
    try:
        n = len(control_points)
    except TypeError:  # not a sequence: _as_float_array says what it is
        return
    if n > MAX_CONTROL_POINTS:
        raise InvalidCurveError(
            f"the curve has {n:,} control points, more than the {MAX_CONTROL_POINTS:,} a "
            "path may have (nurbs.MAX_CONTROL_POINTS); split the path or join its chords")


class NurbsCurve:
    """A clamped non-uniform rational B-spline curve in any number of axes.

    Parameters
    ----------
    degree : int
        Polynomial degree ``p >= 1``.
    knots : array_like, shape (n + p + 1,)
        Clamped, non-decreasing knot vector. Normalised to ``[0, 1]`` on construction.
    control_points : array_like, shape (n, n_axes)
        Control points, ``n >= p + 1``, ``n_axes >= 1`` [path units].
    weights : array_like, shape (n,), optional
        Positive finite weights; all ones (a non-rational B-spline) when omitted.
    name : str, optional
        A label carried into files and reports.
    units : str, optional
        Length unit of the control points (``"pulse"``, ``"mm"``, ...).

    Raises
    ------
    InvalidCurveError
        On any invalid input, naming the offending value.

    Examples
    --------
    >>> from nurbsmotion import make_circle
    >>> c = make_circle(radius=2.0)
    >>> c([0.0, 0.25]).round(12)
    array([[2., 0.],
           [0., 2.]])
    """

    def __init__(
        self,
        degree: int,
        knots: Any,
        control_points: Any,
        weights: Any = None,
        *,
        name: str | None = None,
        units: str | None = None,
    ):
        if isinstance(degree, bool) or not isinstance(degree, (int, np.integer)):
            raise InvalidCurveError(
                f"degree must be an integer >= 1, got {degree!r} ({type(degree).__name__})")
        p = int(degree)
        if p < 1:
            raise InvalidCurveError(f"degree must be an integer >= 1, got {p}")
        if p > MAX_DEGREE:
            raise InvalidCurveError(
                f"degree {p} is above the largest supported degree {MAX_DEGREE} (MAX_DEGREE)")
        if units is not None and units not in PATH_UNITS:
            raise InvalidCurveError(
                f"unit {units!r} is unknown; use one of {', '.join(PATH_UNITS)}")
        if name is not None and not isinstance(name, str):
            raise InvalidCurveError(f"name must be a string, got {name!r:.80}")

        _check_count(control_points)
        P = _as_float_array(control_points, "control_points", 2)
        n, n_axes = P.shape
        if n_axes < 1:
            raise InvalidCurveError("control_points must have at least one axis (column)")
        if n < p + 1:
            raise InvalidCurveError(
                f"a degree-{p} curve needs at least p + 1 = {p + 1} control points, got {n}"
            )
        if not np.all(np.isfinite(P)):
            i = _first_bad(~np.all(np.isfinite(P), axis=1))
            raise InvalidCurveError(f"control point {i} is not finite: {P[i].tolist()}")

        if weights is None:
            w = np.ones(n)
        else:
            w = _as_float_array(weights, "weights", 1)
            if w.shape != (n,):
                raise InvalidCurveError(
                    f"weights has {w.size} entries, expected {n} (one per control point)"
                )
            if not np.all(np.isfinite(w)):
                i = _first_bad(~np.isfinite(w))
                raise InvalidCurveError(f"weight {i} is not finite: {w[i]}")
            if np.any(w <= 0):
                i = _first_bad(w <= 0)
                raise InvalidCurveError(f"weight {i} is {w[i]:g}; weights must be > 0")
        size = _check_magnitudes(P, w)

        t = _as_float_array(knots, "knots", 1)
        if t.size != n + p + 1:
            raise InvalidCurveError(
                f"knot vector has {t.size} entries, expected {n + p + 1} = n + p + 1 "
                f"(n = {n} control points, p = {p})"
            )
        if not np.all(np.isfinite(t)):
            i = _first_bad(~np.isfinite(t))
            raise InvalidCurveError(f"knot {i} is not finite: {t[i]}")
        if np.any(np.diff(t) < 0):
            i = _first_bad(np.diff(t) < 0)
            raise InvalidCurveError(
                f"knots must be non-decreasing, but knot {i + 1} = {t[i + 1]:g} "
                f"< knot {i} = {t[i]:g}"
            )
        if not (np.all(t[: p + 1] == t[0]) and np.all(t[-p - 1 :] == t[-1])):
            raise InvalidCurveError(
                f"knot vector is not clamped: the first and last p + 1 = {p + 1} knots must "
                f"be equal, got start {t[: p + 1].tolist()} and end {t[-p - 1 :].tolist()} "
                "(unclamped knot vectors are not supported)"
            )
        if t[-1] == t[0]:
            raise InvalidCurveError(f"knot vector spans an empty domain [{t[0]:g}, {t[-1]:g}]")
        for end in (t[0], t[-1]):
            # More than p + 1 end knots would make the end basis function vanish, so the
            # curve would not start (end) on its first (last) control point.
            m = int(np.count_nonzero(t == end))
            if m > p + 1:
                raise InvalidCurveError(
                    f"end knot {end:g} has multiplicity {m}, more than p + 1 = {p + 1}"
                )
        interior, counts = np.unique(t[p + 1 : -p - 1], return_counts=True)
        if np.any(counts > p):
            i = _first_bad(counts > p)
            raise InvalidCurveError(
                f"interior knot {interior[i]:g} has multiplicity {counts[i]}, "
                f"more than the degree {p}"
            )

        span = np.diff(t) / (t[-1] - t[0])
        tiny = (span > 0) & (span < MIN_KNOT_SPAN)
        if np.any(tiny):
            i = _first_bad(tiny)
            raise InvalidCurveError(
                f"the knot span [{t[i]:.17g}, {t[i + 1]:.17g}] (knots {i} and {i + 1}) is {span[i]:.3g} of the knot "
                f"domain, shorter than a double can resolve ({MIN_KNOT_SPAN:.3g}): make its "
                "knots equal (a repeated knot) or move them apart")
        domain = (float(t[0]), float(t[-1]))
        t = (t - t[0]) / (t[-1] - t[0])
        for arr in (t, P, w):
            arr.flags.writeable = False
        self.degree = p
        self.knots = t
        self.control_points = P
        self.weights = w
        self.domain = domain
        self.name = name
        self.units = units
        self._size = size  # the control points' largest range over an axis, used as a scale

        homogeneous = np.hstack([P * w[:, None], w[:, None]])
        homogeneous.flags.writeable = False
        self._homogeneous = homogeneous  # [w*P, w], shape (n, n_axes + 1)
        self._spline = self._mirror = None  # scipy reference, built on first use
        self._geometry = None
        self._zero_speed = None  # zero_speed_points, computed on first use
        self._corners: dict[float, np.ndarray] = {}  # sharp_corners per tolerance
        self._ends = None  # end_points, computed on first use
        self._power = None  # power_form, computed on first use
        self._check_not_degenerate()

    # ------------------------------------------------------------------ basic facts
    @property
    def n_axes(self) -> int:
        """Number of axes (columns of the control points)."""
        return self.control_points.shape[1]

    @property
    def n_control_points(self) -> int:
        """Number of control points ``n``."""
        return self.control_points.shape[0]

    @property
    def homogeneous(self) -> np.ndarray:
        """Homogeneous control points ``[w*P, w]``, shape (n_control_points, n_axes + 1)
        (read-only)."""
        return self._homogeneous

    @property
    def breakpoints(self) -> np.ndarray:
        """Distinct knot values in ``[0, 1]``, shape (n_spans + 1,)."""
        return np.unique(self.knots)

    def knot_multiplicity(self, u: Any) -> Any:
        """Number of knots equal to ``u``: an int for a number, an int array of the
        shape of ``u`` for an array (two binary searches of the sorted knots each)."""
        u_arr = np.asarray(u, dtype=float)
        count = (np.searchsorted(self.knots, u_arr, side="right")
                 - np.searchsorted(self.knots, u_arr, side="left"))
        return int(count) if u_arr.ndim == 0 else count

    def __repr__(self) -> str:
        label = f" {self.name!r}" if self.name else ""
        return (
            f"<NurbsCurve{label}: degree {self.degree}, {self.n_control_points} control "
            f"points, {self.n_axes} axes, {len(self.breakpoints) - 1} spans>"
        )

    def to_dict(self) -> dict:
        """Plain-Python description (degree, knots, control_points, weights, name, units)."""
        out: dict[str, Any] = {
            "degree": self.degree,
            "knots": self.knots.tolist(),
            "control_points": self.control_points.tolist(),
            "weights": self.weights.tolist(),
        }
        if self.name is not None:
            out["name"] = self.name
        if self.units is not None:
            out["units"] = self.units
        return out

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, NurbsCurve):
            return NotImplemented
        return (
            self.degree == other.degree
            and np.array_equal(self.knots, other.knots)
            and np.array_equal(self.control_points, other.control_points)
            and np.array_equal(self.weights, other.weights)
        )

    __hash__ = None  # type: ignore[assignment]

    # ------------------------------------------------------------------ evaluation
    def _check_parameter(self, u: Any) -> np.ndarray:
        if isinstance(u, (float, np.ndarray)) and np.asarray(u).dtype.kind == "f":
            uu = np.asarray(u, dtype=float)  # the hot path: no copy
        else:
            try:
                uu = _as_float_array(u, "curve parameter u", np.ndim(np.asarray(u, object)))
            except (InvalidCurveError, ValueError) as exc:
                raise InvalidArgumentError(str(exc)) from None
        # One min/max pass for the common valid case (NaN fails both comparisons).
        if uu.size and uu.min() >= 0.0 and uu.max() <= 1.0:
            return uu
        if not np.all(np.isfinite(uu)):
            raise InvalidArgumentError(
                f"curve parameter must be finite, got {uu[~np.isfinite(uu)][:3]}")
        if np.any((uu < 0.0) | (uu > 1.0)):
            bad = uu[(uu < 0.0) | (uu > 1.0)]
            raise InvalidArgumentError(
                f"curve parameter must lie in [0, 1], got {float(bad.flat[0])!r}")
        return uu

    def derivatives(self, u: Any, max_order: int = 2, side: str = "right") -> np.ndarray:
        """Point and derivatives up to ``max_order`` at once (The NURBS Book, A4.2).

        Evaluated by the compiled kernels of :mod:`nurbsmotion._kernels` (span search,
        A2.3 basis derivatives, A4.2); :meth:`_derivatives_reference` is the independent
        scipy route they are tested against.

        Parameters
        ----------
        u : float or array_like
            Curve parameter(s) in ``[0, 1]``.
        max_order : int
            Highest derivative order, 0 to 3.
        side : {"right", "left"}
            Which one-sided derivative to take at a knot where the curve is not smooth.

        Returns
        -------
        ndarray, shape (max_order + 1,) + shape(u) + (n_axes,)
            ``out[k]`` is the k-th derivative with respect to ``u`` [path units].
        """
        uu = self._check_derivative_request(u, max_order, side)
        from ._kernels import rational_derivatives

        out = rational_derivatives(self.knots, self._homogeneous, self.degree,
                                   np.ascontiguousarray(uu.ravel()), max_order, side == "left")
        return out.reshape((max_order + 1,) + uu.shape + (self.n_axes,))

    def _check_derivative_request(self, u: Any, max_order: int, side: str) -> np.ndarray:
        if (isinstance(max_order, bool) or not isinstance(max_order, (int, np.integer))
                or not 0 <= max_order <= MAX_ORDER):
            raise InvalidArgumentError(
                f"derivative order must be an integer 0..{MAX_ORDER}, got {max_order!r}")
        if side not in ("right", "left"):
            raise InvalidArgumentError(f"side must be 'right' or 'left', got {side!r}")
        return self._check_parameter(u)

    def _derivatives_reference(self, u: Any, max_order: int = 2,
                               side: str = "right") -> np.ndarray:
        """:meth:`derivatives` through scipy's ``BSpline`` in homogeneous coordinates.

        The readable reference the compiled kernels are tested against; the left-sided
        values come from the mirrored spline evaluated at ``1 - u``.
        """
        uu = self._check_derivative_request(u, max_order, side)
        if self._spline is None:
            homogeneous = self._homogeneous
            t = self.knots
            p = self.degree
            from scipy.interpolate import BSpline  # lazily: importing it costs ~0.5 s

            self._spline = BSpline(t, homogeneous, p, extrapolate=True)
            # The mirrored curve evaluated at 1 - u gives left-sided values at breakpoints.
            self._mirror = BSpline(1.0 - t[::-1], homogeneous[::-1], p, extrapolate=True)
        if side == "right":
            hom = [self._spline(uu, nu=k) for k in range(max_order + 1)]
        else:
            hom = [(-1) ** k * self._mirror(1.0 - uu, nu=k) for k in range(max_order + 1)]
        A = [h[..., :-1] for h in hom]
        wd = [h[..., -1:] for h in hom]
        out = np.empty((max_order + 1,) + uu.shape + (self.n_axes,))
        for k in range(max_order + 1):
            v = A[k].copy()
            for i in range(1, k + 1):
                v -= math.comb(k, i) * wd[i] * out[k - i]
            out[k] = v / wd[0]
        return out

    def __call__(self, u: Any, order: int = 0, side: str = "right") -> np.ndarray:
        """Evaluate the curve or its ``order``-th derivative with respect to ``u``.

        Parameters
        ----------
        u : float or array_like, shape (m,)
            Curve parameter(s) in ``[0, 1]``.
        order : int
            Derivative order, 0 (point) to 3 (for jerk).
        side : {"right", "left"}
            One-sided derivative at a knot of full multiplicity.

        Returns
        -------
        ndarray, shape (m, n_axes) (or (n_axes,) for a scalar ``u``)
            Points [path units] or derivatives [path units / unit u^order].
        """
        return self.derivatives(u, order, side)[order]

    @property
    def end_points(self) -> np.ndarray:
        """``[C(0), C(1)]``, shape (2, n_axes) [path units] (read-only; computed once)."""
        if self._ends is None:
            ends = self(np.array([0.0, 1.0]))
            ends.flags.writeable = False
            self._ends = ends
        return self._ends

    @property
    def power_form(self) -> tuple[np.ndarray, np.ndarray]:
        """The homogeneous curve ``[w*C, w]`` as a polynomial on each span (computed once,
        read-only; :func:`nurbsmotion._kernels.power_basis`).

        Returns
        -------
        spans : ndarray, shape (m + 1,)
            The distinct knots, 0 .. 1.
        coefficients : ndarray, shape (m, p + 1, n_axes + 1)
            ``[w*C, w](u) = sum_k coefficients[i, k] * (u - spans[i])**k`` on span i.
        """
        if self._power is None:
            from ._kernels import power_basis

            spans = np.array(self.breakpoints, dtype=float)
            coefficients = power_basis(self.knots, self._homogeneous, self.degree, spans[:-1])
            spans.flags.writeable = coefficients.flags.writeable = False
            self._power = (spans, coefficients)
        return self._power

    def _weight(self, u: np.ndarray) -> np.ndarray:
        """w(u), right-sided, for parameters ``u`` in [0, 1] (the power form, Horner)."""
        spans, coefficients = self.power_form
        i = np.clip(np.searchsorted(spans, u, side="right") - 1, 0, len(spans) - 2)
        t = u - spans[i]
        c = coefficients[i, :, -1]
        w = c[:, -1].copy()
        for k in range(self.degree - 1, -1, -1):
            w = w * t + c[:, k]
        return w

    # ------------------------------------------------------------------ geometry
    @property
    def geometry(self):
        """Cached :class:`nurbsmotion.geometry.CurveGeometry` (arc length table etc.)."""
        if self._geometry is None:
            from .geometry import CurveGeometry

            self._geometry = CurveGeometry(self)
        return self._geometry

    @property
    def length(self) -> float:
        """Total arc length [path units]."""
        return self.geometry.length

    def arc_length(self, u: Any) -> np.ndarray:
        """Arc length ``s(u)`` from the start [path units], to 1e-9 relative or better."""
        return self.geometry.arc_length(u)

    def parameter_at(self, s: Any) -> np.ndarray:
        """Inverse arc length ``u(s)``; ``s`` in ``[0, length]`` [path units]."""
        return self.geometry.parameter_at(s)

    def tangent(self, u: Any, side: str = "right") -> np.ndarray:
        """Unit tangent, shape ``shape(u) + (n_axes,)``; the limit tangent
        (:meth:`limit_tangent`) where ``C'(u) = 0``."""
        d1 = self(u, 1, side)
        norm = np.linalg.norm(d1, axis=-1, keepdims=True)
        scale = self._size
        if np.any(norm <= 1e-9 * scale):
            return self.limit_tangent(u, side)
        return d1 / norm

    def curvature(self, u: Any, side: str = "right") -> np.ndarray:
        """Curvature ``|C' x C''| / |C'|^3`` in any dimension [1 / path unit]."""
        d = self.derivatives(u, 2, side)
        return curvature_from_derivatives(d[1], d[2])

    def sharp_corners(self, angle_tolerance: float = 1e-6) -> np.ndarray:
        """Parameters of interior knots where the tangent direction jumps.

        Parameters
        ----------
        angle_tolerance : float
            Smallest turning angle counted as a corner [rad].

        Returns
        -------
        ndarray, shape (n_corners,)
            Sorted corner parameters in ``(0, 1)``.
        """
        tol = angle_tolerance
        if isinstance(tol, bool) or not isinstance(tol, (int, float, np.integer, np.floating)) \
                or not 0 <= tol < math.pi:
            raise InvalidArgumentError(
                f"angle_tolerance must be a number in [0, pi) rad, got {angle_tolerance!r}")
        tol = float(tol)
        if tol not in self._corners:  # computed once per tolerance, without the arc length
            from .geometry import sharp_corners

            self._corners[tol] = sharp_corners(self, tol)
        return self._corners[tol].copy()

    def turning_angle(self, u: Any) -> np.ndarray:
        """Angle between the left and right tangents at ``u`` [rad] (0 where smooth)."""
        cos = np.sum(self.tangent(u, "left") * self.tangent(u, "right"), axis=-1)
        return np.arccos(np.clip(cos, -1.0, 1.0))

    def reversed(self) -> "NurbsCurve":
        """The same curve traversed from end to start."""
        return NurbsCurve(
            self.degree,
            1.0 - self.knots[::-1],
            self.control_points[::-1],
            self.weights[::-1],
            name=self.name,
            units=self.units,
        )

    def scaled(self, factor: float, units: str | None = None) -> "NurbsCurve":
        """The curve with every coordinate multiplied by ``factor`` (e.g. mm to pulses)."""
        if isinstance(factor, bool) or not isinstance(factor, (int, float, np.integer,
                                                                np.floating)) \
                or not (np.isfinite(factor) and factor > 0):
            raise InvalidCurveError(f"scale factor must be finite and > 0, got {factor!r}")
        return NurbsCurve(
            self.degree,
            self.knots,
            self.control_points * factor,
            self.weights,
            name=self.name,
            units=units if units is not None else self.units,
        )

    # ------------------------------------------------------------------ validation
    def _check_not_degenerate(self) -> None:
        P = self.control_points
        scale = self._size
        if scale == 0.0:
            raise InvalidCurveError(
                f"degenerate curve: all {len(P)} control points coincide at {P[0].tolist()} "
                "(zero length)"
            )
        # A knot span whose p + 1 control points coincide is a piece of zero length (the
        # curve stands still over it): it has no tangent, and a run refused it late while
        # bound and the figures divided by its zero speed (issue 37). Exact, as the
        # polyline's check: with positive weights a span is one point only then.
        p, U = self.degree, self.knots
        same = P[1:, 0] == P[:-1, 0]  # (n - 1,): a control point equal to the previous one
        for j in range(1, P.shape[1]):
            same &= P[1:, j] == P[:-1, j]
        run = np.concatenate([[0], np.cumsum(same)])
        # the span's p + 1 points i..i + p coincide: p equal neighbours in a row
        still = (run[p:] - run[:-p] == p) & (U[p + 1:len(P) + 1] > U[p:len(P)])
        if np.any(still):
            i = int(np.flatnonzero(still)[0])
            raise InvalidCurveError(
                f"degenerate curve: knot span [{U[i + p]:.6g}, {U[i + p + 1]:.6g}] is a piece of "
                f"zero length (its {p + 1} control points {i}..{i + p} coincide at "
                f"{P[i].tolist()}); remove the repeated control point")

    @property
    def zero_speed_points(self) -> np.ndarray:
        """Parameters where ``C'(u) = 0`` (to 1e-9 of the curve's size), sorted, shape (k,).

        Such points are accepted (a control point repeated at an end or inside, as CAM
        and LinuxCNC's own G5.2 examples write them): the curve keeps its exact geometry.
        There the tangent is the limit tangent (:meth:`limit_tangent`); where the limit
        tangents from both sides differ (a cusp, a genuine reversal) the point is a sharp
        corner (:meth:`sharp_corners`). Computed on first use: on each span the numerator
        of ``C' = (A' w - A w') / w^2`` is a polynomial of degree ``2p - 2`` per axis
        (``A, w``: the homogeneous spline), interpolated exactly at Chebyshev nodes; its
        real roots and the span's ends (one-sided) are the candidates.
        """
        if self._zero_speed is None:
            self._zero_speed = self._find_zero_speed()
        return self._zero_speed.copy()

    def _find_zero_speed(self) -> np.ndarray:
        P = self.control_points
        scale = self._size
        # All spans at once, so that a path of 10^6 spans is checked in seconds.
        p = self.degree
        if p == 1:  # C' is constant on each span: zero where two control points coincide
            same = np.all(P[1:] == P[:-1], axis=1)
            t = self.knots  # span i, from P_i to P_i+1, is [t_(i+1), t_(i+2)]
            return np.unique(np.concatenate([t[1:-2][same], t[2:-1][same]]))
        which = self._spans_that_may_stop()
        if which.size == 0:
            return np.zeros(0)
        a, b, cand = self._axis_turns(which)
        ok = ~np.isnan(cand)
        u_in = np.concatenate([a, cand[ok & (cand < b[:, None])]])
        u_end = np.concatenate([b, cand[ok & (cand >= b[:, None])]])
        speed = np.concatenate([np.linalg.norm(self(u_in, 1, "right"), axis=-1),
                                np.linalg.norm(self(u_end, 1, "left"), axis=-1)])
        where = np.concatenate([u_in, u_end])
        bad = speed <= 1e-9 * scale
        if not np.any(bad):
            return np.zeros(0)
        u = np.sort(where[bad])
        # a root found within rounding of a knot is that knot (the spans meet there)
        bp = self.breakpoints
        near = np.clip(np.searchsorted(bp, u), 1, len(bp) - 1)
        near = np.where(np.abs(bp[near - 1] - u) < np.abs(bp[near] - u), near - 1, near)
        u = np.where(np.abs(bp[near] - u) <= 1e-12, bp[near], u)
        u = u[np.concatenate([[True], np.diff(u) > 1e-12])]
        # A multiple root (a control point repeated p times) is found only to about
        # eps^(1/m): candidates between which the curve does not move (to the same 1e-9
        # of its size, at both ends and halfway) are one point, a breakpoint if one of
        # them is.
        if len(u) > 1:
            mid = self(0.5 * (u[1:] + u[:-1]))
            pos = self(u)
            same = (np.linalg.norm(pos[1:] - pos[:-1], axis=-1) <= 1e-9 * scale) \
                & (np.linalg.norm(mid - pos[:-1], axis=-1) <= 1e-9 * scale)
            groups = np.split(u, np.flatnonzero(~same) + 1)
            on_bp = [g[np.isin(g, bp)] for g in groups]
            u = np.array([b[0] if b.size else 0.5 * (g[0] + g[-1])
                          for g, b in zip(groups, on_bp)])
        return u

    def _span_first_points(self) -> np.ndarray:
        """Index of the first of the ``p + 1`` control points of each knot span (between
        consecutive :attr:`breakpoints`), shape (spans,): span ``[u_k, u_k+1)`` is
        shaped by control points ``k - p .. k`` (The NURBS Book, P2.2)."""
        k = np.searchsorted(self.knots, self.breakpoints[:-1], side="right") - 1
        return k - self.degree

    def _spans_that_may_stop(self) -> np.ndarray:
        """Indices of the knot spans on which ``|C'|`` may come within 1e-9 of the curve's
        size (:attr:`zero_speed_points`), sorted. For a non-rational curve (equal
        weights) ``C'`` on a span is a convex combination of its hodograph's control
        points ``Q_i = p (P_i+1 - P_i) / (u_i+p+1 - u_i+1)`` (The NURBS Book, Eq. 3.7),
        so a span where one axis's ``Q_i`` are all above twice that threshold (or all
        below its negative) moves at more than it everywhere, and is left out: on a CAM
        spline along an axis this leaves none, in one vectorised pass. Every span of a
        rational curve."""
        spans = len(self.breakpoints) - 1
        w = self.weights
        if not np.all(w == w[0]):
            return np.arange(spans)
        p, P, U = self.degree, self.control_points, self.knots
        du = U[p + 1:len(P) + p] - U[1:len(P)]  # (n - 1,): > 0 wherever a span uses Q_i
        with np.errstate(divide="ignore", invalid="ignore"):
            Q = p * np.diff(P, axis=0) / du[:, None]
        window = np.lib.stride_tricks.sliding_window_view(Q, p, axis=0)  # (n - p, axes, p)
        first = self._span_first_points()
        margin = 2e-9 * self._size
        lo = window.min(axis=2)[first]
        hi = window.max(axis=2)[first]
        moving = np.any((lo > margin) | (hi < -margin), axis=1)
        return np.flatnonzero(~moving)

    def _axis_turns(self, which: np.ndarray | None = None
                    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per span ``[a, b]``, the parameters where one axis's derivative ``C'_j``
        vanishes, for degree >= 2: on each span the numerator of
        ``C' = (A' w - A w') / w^2`` is a polynomial of degree ``2p - 2`` per axis (``A,
        w``: the homogeneous spline), interpolated exactly at Chebyshev nodes; its real
        roots, clipped to the span.

        Parameters
        ----------
        which : ndarray of int, optional
            Indices of the knot spans to look at (every span by default); each span's
            roots are computed alone, so a subset gives the same values.

        Returns
        -------
        a, b : ndarray, shape (spans,)
        roots : ndarray, shape (spans, n_axes * (2p - 2))
            NaN where there is none.
        """
        p = self.degree
        bp = self.breakpoints
        nodes = np.polynomial.chebyshev.chebpts1(2 * p - 1)
        a, b = bp[:-1], bp[1:]
        if which is not None:
            a, b = a[which], b[which]
        uu = (0.5 * (a + b))[:, None] + (0.5 * (b - a))[:, None] * nodes  # (spans, nodes)
        weight = self._weight(uu.ravel()).reshape(uu.shape)
        numerator = self(uu.ravel(), 1).reshape(uu.shape + (-1,)) * weight[..., None] ** 2
        # Chebyshev coefficients of every span and axis, shape (spans, 2p - 1, axes).
        coef = np.einsum("kn,snj->skj", np.linalg.pinv(
            np.polynomial.chebyshev.chebvander(nodes, 2 * p - 2)), numerator)
        big = np.max(np.abs(coef), axis=(1, 2))
        roots = _chebyshev_roots(np.moveaxis(coef, 2, 1), 1e-12 * big[:, None])
        # roots: (spans, axes, 2p - 2) in [-1, 1] or NaN
        r = roots.reshape(len(a), -1)
        return a, b, np.clip((0.5 * (a + b))[:, None] + (0.5 * (b - a))[:, None] * r,
                             a[:, None], b[:, None])

    def bounding_box(self) -> np.ndarray:
        """The exact axis-aligned bounding box, shape (2, n_axes): lower and upper corner
        [path units]. Each coordinate's extremes lie at a span's end or where its
        derivative vanishes (:meth:`_axis_turns`); a polyline's are its vertices.

        Linear in the spans: with weights > 0 a span lies in the box of its ``p + 1``
        control points (the convex hull property, The NURBS Book P4.4), so only a span
        whose control points pass outside the box of the curve's breakpoints can hold
        an extreme, and only there are the derivative's roots looked for (on a CAM
        spline of a million spans: a few per bump instead of every span)."""
        if self.degree == 1:
            pts = self.control_points
        else:
            pts = self(self.breakpoints)
            lo, hi = pts.min(axis=0), pts.max(axis=0)
            window = np.lib.stride_tricks.sliding_window_view(
                self.control_points, self.degree + 1, axis=0)  # (n - p, axes, p + 1)
            first = self._span_first_points()
            outside = (window.min(axis=2)[first] < lo) | (window.max(axis=2)[first] > hi)
            which = np.flatnonzero(np.any(outside, axis=1))
            if which.size:
                _, _, turns = self._axis_turns(which)
                pts = np.vstack([pts, self(turns[~np.isnan(turns)])])
        return np.array([pts.min(axis=0), pts.max(axis=0)])

    def limit_tangent(self, u: Any, side: str = "right") -> np.ndarray:
        """Unit tangent, also where ``C'(u) = 0``: the direction of motion just after
        (``side="right"``) or just before (``"left"``) ``u``, shape ``shape(u) + (n_axes,)``.

        Where ``|C'(u)|`` vanishes, the first non-zero derivative ``C^(k)`` gives it:
        ``C'(u + h) ~ C^(k)(u) h^(k-1) / (k-1)!``, so the right limit is ``C^(k)`` and the
        left limit ``(-1)^(k-1) C^(k)``. Beyond the third derivative the direction of
        the chord to a point 1e-6 away in the parameter is used.
        """
        uu = np.asarray(u, dtype=float)
        d = self.derivatives(uu.ravel(), 3, side)  # (4, m, axes)
        scale = self._size
        out = d[1].copy()
        norm = np.linalg.norm(out, axis=-1)
        todo = norm <= 1e-9 * scale
        sign = 1.0
        for k in (2, 3):
            if not np.any(todo):
                break
            sign = 1.0 if side == "right" else (-1.0) ** (k - 1)
            nk = np.linalg.norm(d[k], axis=-1)
            use = todo & (nk > 1e-9 * scale)
            out[use] = sign * d[k][use]
            todo &= ~use
        if np.any(todo):
            flat = uu.ravel()[todo]
            h = 1e-6 if side == "right" else -1e-6
            other = np.clip(flat + h, 0.0, 1.0)
            out[todo] = (self(other) - self(flat)) * np.sign(other - flat)[:, None]
        out /= np.linalg.norm(out, axis=-1, keepdims=True)
        return out.reshape(uu.shape + (self.n_axes,))


def _chebyshev_roots(coef: np.ndarray, tol: np.ndarray) -> np.ndarray:
    """Real roots in [-1, 1] of many Chebyshev series at once.

    Parameters
    ----------
    coef : ndarray, shape (..., d + 1)
        Coefficients, lowest first.
    tol : ndarray, shape (...)
        A series whose coefficients are all below ``tol`` is taken as identically zero
        (no roots); trailing coefficients below it are dropped.

    Returns
    -------
    ndarray, shape (..., d)
        The real roots in [-1, 1], NaN-padded (numpy's ``chebroots``, batched by degree).
    """
    shape, d = coef.shape[:-1], coef.shape[-1] - 1
    c = coef.reshape(-1, d + 1)
    t = np.broadcast_to(tol, shape).ravel()
    out = np.full((c.shape[0], max(d, 0)), np.nan)
    significant = np.abs(c) > t[:, None]
    degree = np.where(significant.any(axis=1),
                      d - np.argmax(significant[:, ::-1], axis=1), 0)
    for n in range(1, d + 1):
        rows = np.flatnonzero(degree == n)
        if rows.size == 0:
            continue
        cn = c[rows, : n + 1]
        if n == 1:
            r = (-cn[:, 0] / cn[:, 1])[:, None].astype(complex)
        else:
            # numpy's chebcompanion, stacked: the same matrix, a different last column.
            mat = np.zeros((n, n))
            scl = np.array([1.0] + [math.sqrt(0.5)] * (n - 1))
            top = mat.reshape(-1)[1 :: n + 1]
            top[0] = math.sqrt(0.5)
            top[1:] = 0.5
            mat.reshape(-1)[n :: n + 1] = top
            mats = np.repeat(mat[None], rows.size, axis=0)
            mats[:, :, -1] -= (cn[:, :-1] / cn[:, -1:]) * (scl / scl[-1]) * 0.5
            r = np.linalg.eigvals(mats)
        real = (np.abs(r.imag) < 1e-7) & (np.abs(r.real) <= 1.0)
        out[rows, :n] = np.where(real, r.real, np.nan)
    return out.reshape(shape + (max(d, 0),))


def curvature_from_derivatives(d1: np.ndarray, d2: np.ndarray) -> np.ndarray:
    """Curvature from first and second derivatives, in any dimension.

    ``kappa = sqrt(|d1|^2 |d2|^2 - (d1 . d2)^2) / |d1|^3``; NaN where ``d1`` vanishes
    (the parametrisation stops there: the curvature is not defined by these derivatives).
    """
    n1 = np.sum(d1 * d1, axis=-1)
    cross2 = np.maximum(n1 * np.sum(d2 * d2, axis=-1) - np.sum(d1 * d2, axis=-1) ** 2, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(n1 > 0.0, np.sqrt(cross2) / n1**1.5, np.nan)[()]


# ---------------------------------------------------------------------- factories
def make_line(start: Any, end: Any, *, name: str | None = None, units: str | None = None):
    """Straight segment from ``start`` to ``end`` (degree 1), shape (n_axes,) each."""
    return make_polyline([start, end], name=name, units=units)


def make_polyline(points: Any, *, name: str | None = None, units: str | None = None):
    """Degree-1 curve through ``points`` (shape (m, n_axes)), knots by chord length.

    Every interior vertex is a knot of full multiplicity, i.e. a sharp corner unless the
    neighbouring segments are collinear.
    """
    P = _as_float_array(points, "points", 2)
    if len(P) < 2:
        raise InvalidCurveError(f"a polyline needs at least 2 points, got {len(P)}")
    if not np.all(np.isfinite(P)):
        raise InvalidCurveError(f"polyline points must be finite, got {P.tolist()}")
    chord = np.linalg.norm(np.diff(P, axis=0), axis=1)
    if np.any(chord == 0):
        i = _first_bad(chord == 0)
        raise InvalidCurveError(
            f"degenerate curve: polyline points {i} and {i + 1} coincide at {P[i].tolist()}"
        )
    s = np.concatenate([[0.0], np.cumsum(chord)])
    knots = np.concatenate([[0.0], s / s[-1], [1.0]])
    knots[-2] = 1.0
    return NurbsCurve(1, knots, P, name=name, units=units)


def make_arc(
    center: Any,
    radius: float,
    start_angle: float,
    end_angle: float,
    *,
    name: str | None = None,
    units: str | None = None,
) -> NurbsCurve:
    """Exact circular arc in the plane as a rational quadratic (The NURBS Book, A7.1).

    Parameters
    ----------
    center : array_like, shape (2,)
        Centre [path units].
    radius : float
        Radius > 0 [path units].
    start_angle, end_angle : float
        Angles from the +x axis [rad]. ``end_angle < start_angle`` runs clockwise. The
        sweep ``|end - start|`` must be in ``(0, 2 pi]``.

    Notes
    -----
    The arc is split into ``ceil(sweep / (pi/2))`` equal pieces, each a rational quadratic
    with middle weight ``cos(half-sweep)``; interior knots are double, where the pieces
    join with equal tangents (the curve is C1 there, not a corner).
    """
    c = _as_float_array(center, "center", 1)
    if c.shape != (2,):
        raise InvalidCurveError(f"arc center must have 2 coordinates, got {c.tolist()}")
    if not (np.isfinite(radius) and radius > 0):
        raise InvalidCurveError(f"arc radius must be finite and > 0, got {radius!r}")
    sweep = float(end_angle) - float(start_angle)
    if not (np.isfinite(sweep) and 0 < abs(sweep) <= 2 * math.pi + 1e-12):
        raise InvalidCurveError(
            f"arc sweep must be in (0, 2 pi] in magnitude, got {sweep!r} rad "
            f"(from {start_angle!r} to {end_angle!r})"
        )
    sweep = math.copysign(min(abs(sweep), 2 * math.pi), sweep)
    n_pieces = max(1, math.ceil(abs(sweep) / (math.pi / 2) - 1e-12))
    d = sweep / n_pieces
    w_mid = math.cos(d / 2)
    points = []
    weights = []
    for i in range(n_pieces):
        a0 = start_angle + i * d
        am = a0 + d / 2
        if i == 0:
            points.append(c + radius * np.array([math.cos(a0), math.sin(a0)]))
            weights.append(1.0)
        points.append(c + radius / w_mid * np.array([math.cos(am), math.sin(am)]))
        weights.append(w_mid)
        a1 = start_angle + (i + 1) * d
        points.append(c + radius * np.array([math.cos(a1), math.sin(a1)]))
        weights.append(1.0)
    interior = np.repeat(np.arange(1, n_pieces) / n_pieces, 2)
    knots = np.concatenate([[0.0] * 3, interior, [1.0] * 3])
    return NurbsCurve(2, knots, points, weights, name=name, units=units)


def make_circle(
    radius: float,
    center: Any = (0.0, 0.0),
    start_angle: float = 0.0,
    *,
    clockwise: bool = False,
    name: str | None = None,
    units: str | None = None,
) -> NurbsCurve:
    """Exact full circle (rational quadratic, 9 control points), starting at ``start_angle``."""
    sweep = -2 * math.pi if clockwise else 2 * math.pi
    return make_arc(
        center, radius, start_angle, start_angle + sweep, name=name or "circle", units=units
    )


BUILTIN_PATHS = {"die-bonder-pi": "die_bonder_pi.json", "butterfly": "butterfly.json"}
"""Built-in benchmark paths (docs/model.md#benchmarks) by name, and their package data files."""


def builtin_path(name: str) -> NurbsCurve:
    """A built-in benchmark path by name (see :data:`BUILTIN_PATHS`)."""
    if name not in BUILTIN_PATHS:
        raise KeyError(f"no built-in path {name!r}; choose from {sorted(BUILTIN_PATHS)}")
    text = resources.files(__package__).joinpath("paths", "data", BUILTIN_PATHS[name]).read_text()
    data = json.loads(text)
    return NurbsCurve(
        data["degree"],
        data["knots"],
        data["control_points"],
        data.get("weights"),
        name=data.get("name", name),
        units=data.get("units"),
    )


def make_die_bonder_pi() -> NurbsCurve:
    """The die-bonder Pi move of docs/model.md#benchmarks [pulse]: cubic, two sharp corners, ~103.1 mm."""
    return builtin_path("die-bonder-pi")


def make_butterfly() -> NurbsCurve:
    """The butterfly benchmark [mm]: cubic, closed, 51 control points, ~382.86 mm."""
    return builtin_path("butterfly")
