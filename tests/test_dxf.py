"""DXF import (SPLINE, LINE, ARC, CIRCLE, LWPOLYLINE with bulges) and SPLINE export."""

from __future__ import annotations

import math
import warnings

import ezdxf
import numpy as np
import pytest

from nurbsmotion import builtin_path, make_circle
from nurbsmotion.errors import PathFileError
from nurbsmotion.paths import load_path, save_path
from nurbsmotion.paths.dxf import DxfWarning, load_dxf, save_dxf


def drawing():
    doc = ezdxf.new("R2010")
    doc.header["$INSUNITS"] = 4  # mm
    return doc, doc.modelspace()


@pytest.mark.parametrize("name", ["butterfly", "die-bonder-pi"])
def test_spline_round_trip(tmp_path, name):
    curve = builtin_path(name)
    file = save_path(curve, tmp_path / "p.dxf")
    (back,) = load_dxf(file)
    size = np.max(np.ptp(curve.control_points, axis=0))
    assert back.degree == curve.degree
    np.testing.assert_allclose(back.knots, curve.knots, rtol=0, atol=1e-15)
    np.testing.assert_allclose(back.control_points, curve.control_points, rtol=0, atol=1e-9 * size)
    np.testing.assert_allclose(back.weights, curve.weights, rtol=1e-15)
    u = np.linspace(0, 1, 1001)
    assert np.max(np.abs(back(u) - curve(u))) <= 1e-9 * size
    assert back.units == ("mm" if curve.units == "mm" else None)  # DXF has no 'pulse'


def test_lines_arcs_and_bulges_chain_in_any_order_and_direction(tmp_path):
    doc, msp = drawing()
    # a slot: bottom line, right half circle (ARC), top line reversed, left half as a bulge
    msp.add_lwpolyline([(0, 10, 1.0), (0, 0, 0)], format="xyb")  # semicircle x<0, CCW
    msp.add_line((20, 10), (0, 10))  # top, drawn right to left
    msp.add_line((0, 0), (20, 0))  # bottom
    msp.add_arc((20, 5), 5, -90, 90)  # right end, CCW from (20,0) to (20,10)
    msp.add_text("slot")
    file = tmp_path / "slot.dxf"
    doc.saveas(file)
    with pytest.warns(DxfWarning, match="ignored annotation entities: 1 TEXT"):
        (c,) = load_dxf(file)
    assert c.units == "mm" and c.name == "slot#1"
    assert c.length == pytest.approx(2 * 20 + 2 * math.pi * 5, rel=1e-12)
    np.testing.assert_allclose(c(0.0), c(1.0), atol=1e-12)  # closed
    assert c.sharp_corners().size == 0  # lines are tangent to both ends
    # every point lies on the slot: distance to the segment y in [0, 10] axis is 5
    pts = c(np.linspace(0, 1, 2001))
    nearest = np.c_[np.clip(pts[:, 0], 0, 20), np.full(len(pts), 5.0)]
    np.testing.assert_allclose(np.linalg.norm(pts - nearest, axis=1), 5.0, atol=1e-12)


def test_mirrored_arc_and_circle(tmp_path):
    doc, msp = drawing()
    # extrusion -Z: OCS x is WCS -x; centre (-3, 0) in OCS is (3, 0) in WCS
    msp.add_arc((-3, 0), 2, 0, 90, dxfattribs={"extrusion": (0, 0, -1)})
    msp.add_circle((50, 0), 4)
    file = tmp_path / "m.dxf"
    doc.saveas(file)
    arc, circle = load_dxf(file)
    np.testing.assert_allclose(arc(0.0), [1.0, 0.0], atol=1e-12)  # OCS (-1, 0)
    np.testing.assert_allclose(arc(1.0), [3.0, 2.0], atol=1e-12)  # OCS (-3, 2)
    np.testing.assert_allclose(np.linalg.norm(arc(np.linspace(0, 1, 50)) - [3, 0], axis=1), 2, atol=1e-12)
    assert circle.length == pytest.approx(8 * math.pi, rel=1e-12)
    with pytest.raises(PathFileError, match=r"holds 2 separate contours"):
        load_path(file)
    assert load_path(f"{file}#2").length == pytest.approx(8 * math.pi, rel=1e-12)


@pytest.mark.parametrize(
    "build,pattern",
    [
        (lambda msp: msp.add_spline(fit_points=[(0, 0), (1, 1), (2, 0), (3, 1)]), r"SPLINE #\w+ is defined by 4 fit points only"),
        (lambda msp: msp.add_text("hello"), r"no usable entity"),
        (lambda msp: msp.add_ellipse((0, 0), (2, 0), 0.5), r"ELLIPSE #\w+: ELLIPSE entities are not supported"),
        (lambda msp: msp.add_arc((0, 0), 1, 0, 90, dxfattribs={"extrusion": (1, 0, 0)}), r"ARC #\w+ is not in the XY plane"),
        (lambda msp: msp.add_spline([(0, 0, 0), (1, 1, 1), (2, 0, 0), (3, 1, 0)]).set_closed([(0, 0, 0), (1, 1, 0), (2, 0, 0), (3, 1, 0)]), r"SPLINE #\w+: knot vector is not clamped"),
        (lambda msp: msp.add_rational_spline([(0, 0), (1, 1), (2, 0)], [1, -1, 1], degree=2), r"SPLINE #\w+: weight 1 is -1"),
    ],
)
def test_unusable_entities_are_named(tmp_path, build, pattern):
    doc, msp = drawing()
    build(msp)
    file = tmp_path / "bad.dxf"
    doc.saveas(file)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DxfWarning)
        with pytest.raises(PathFileError, match=pattern):
            load_dxf(file)
    assert [p.name for p in tmp_path.iterdir()] == ["bad.dxf"]


def test_not_a_dxf_and_huge_garbage_fail_fast(tmp_path):
    from test_path_files import assert_fails_fast, write_garbage

    text = tmp_path / "text.dxf"
    text.write_text("hello world\n")
    with pytest.raises(PathFileError, match="not a DXF file"):
        load_dxf(text)
    path = write_garbage(tmp_path / "garbage.dxf")
    assert_fails_fast(load_dxf, path, r"garbage\.dxf, line 1: not a DXF file")


def test_export_refuses_three_axes(tmp_path):
    curve = make_circle(1.0)
    from nurbsmotion import NurbsCurve

    c3 = NurbsCurve(curve.degree, curve.knots, np.c_[curve.control_points, np.ones(9)], curve.weights)
    with pytest.raises(PathFileError, match="writes XY paths; the curve has 3 axes"):
        save_dxf(c3, tmp_path / "c.dxf")
    assert list(tmp_path.iterdir()) == []
