"""DXF import (SPLINE, LINE, ARC, CIRCLE, LWPOLYLINE with bulges) and SPLINE export."""

from __future__ import annotations

import math
import re
import warnings

import ezdxf
import ezdxf.recover
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

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
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        (back,) = load_dxf(file)
    assert back.units == "mm"
    assert bool(caught) == (curve.units != "mm")
    size = np.max(np.ptp(curve.control_points, axis=0))
    assert back.degree == curve.degree
    np.testing.assert_allclose(back.knots, curve.knots, rtol=0, atol=1e-15)
    np.testing.assert_allclose(back.control_points, curve.control_points, rtol=0, atol=1e-9 * size)
    np.testing.assert_allclose(back.weights, curve.weights, rtol=1e-15)
    u = np.linspace(0, 1, 1001)
    assert np.max(np.abs(back(u) - curve(u))) <= 1e-9 * size
    # DXF has no 'pulse': such a drawing declares no unit and reads as mm with a warning


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
    with pytest.warns(DxfWarning, match="1 TEXT entity skipped"):
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
        (lambda msp: msp.add_text("hello"), r"no path entity in the model space"),
        (lambda msp: msp.add_arc((0, 0), 1, 0, 90, dxfattribs={"extrusion": (1, 0, 0)}), r"ARC #\w+ is not flat: Z runs from"),
        (lambda msp: msp.add_rational_spline([(0, 0), (1, 1), (2, 0)], [1, -1, 1], degree=2), r"SPLINE #\w+: weights must be finite and > 0"),
        (lambda msp: msp.add_arc((0, 0), -5, 0, 90), r"ARC #\w+: radius -5 must be > 0"),
        (lambda msp: msp.add_circle((0, 0), 0), r"no path entity in the model space .*; 1 CIRCLE of zero length \(#\w+\)"),
        (lambda msp: msp.add_lwpolyline([(0, 0, 1e300), (1, 0, 0)], format="xyb"), r"LWPOLYLINE #\w+: bulge 1e\+300 is beyond the largest read, 1e\+06"),
        (lambda msp: msp.add_lwpolyline([(0, 0, math.inf), (1, 0, 0)], format="xyb"), r"LWPOLYLINE #\w+: bulge inf is not finite"),
        (lambda msp: msp.add_line((0, 0), (1e300, 0)), r"LINE #\w+: a point \[1e\+300, 0.0, 0.0\] is not finite or beyond"),
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


@pytest.mark.parametrize("ratio", ["0.0", "1e-12"])
def test_a_flat_ellipse_is_refused_as_ezdxf_rules(tmp_path, ratio):
    # Issue 37: an ELLIPSE of ratio 0 is its major axis traversed there and back, not an
    # ellipse. ezdxf will not write it (its is_valid_ratio: 1e-10 <= ratio <= 1) and its
    # audit sets it to 1e-10, a needle whose ends `paper` saturated on; read, it is refused
    # naming the entity, the ratio and ezdxf's limit.
    from ezdxf.entities.ellipse import MIN_RATIO, is_valid_ratio

    assert not is_valid_ratio(float(ratio))
    doc, msp = drawing()
    msp.add_ellipse((0, 0), major_axis=(10, 0), ratio=0.5)
    file = tmp_path / "flat.dxf"
    doc.saveas(file)
    text = file.read_text()
    at = text.index("\n 40\n", text.index("AcDbEllipse"))
    end = text.index("\n", at + 5)
    file.write_text(text[:at] + "\n 40\n" + ratio + text[end:])
    with pytest.raises(PathFileError, match=rf"ELLIPSE #\w+: axis ratio {float(ratio)!r} is "
                       rf"below the smallest valid one, {MIN_RATIO:g} \(ezdxf's check\)"):
        load_path(file)
    # the smallest valid ratio is read as the exact ellipse it is
    file.write_text(text[:at] + "\n 40\n1e-10" + text[end:])
    curve = load_path(file)
    np.testing.assert_allclose(curve.bounding_box(), [[-10, -1e-9], [10, 1e-9]], atol=1e-12)


def test_export_refuses_three_axes(tmp_path):
    curve = make_circle(1.0)
    from nurbsmotion import NurbsCurve

    c3 = NurbsCurve(curve.degree, curve.knots, np.c_[curve.control_points, np.ones(9)], curve.weights)
    with pytest.raises(PathFileError, match="writes XY paths; the curve has 3 axes"):
        save_dxf(c3, tmp_path / "c.dxf")
    assert list(tmp_path.iterdir()) == []


# ---------------------------------------------------------------- ezdxf as the reference
def distance_to(curves, points):
    from linuxcnc_reference import distances_to_path

    return distances_to_path(np.asarray(points, dtype=float), curves)


def ezdxf_points(entity, n: int = 200) -> np.ndarray:
    """Points of an entity as ezdxf itself evaluates it, shape (n, 3)."""
    kind = entity.dxftype()
    if kind == "SPLINE":
        tool = entity.construction_tool()
        return np.array(list(tool.points(np.linspace(tool.knots()[tool.degree], tool.knots()[-tool.degree - 1], n))))
    if kind == "ELLIPSE":
        e = entity.construction_tool()
        t1 = e.end_param if e.end_param > e.start_param else e.end_param + 2 * math.pi
        return np.array(list(e.vertices(np.linspace(e.start_param, t1, n))))
    if kind == "LINE":
        start, end = (np.array(tuple(v), dtype=float) for v in (entity.dxf.start, entity.dxf.end))
        return start + np.linspace(0.0, 1.0, n)[:, None] * (end - start)
    if kind in ("ARC", "CIRCLE"):  # ezdxf's vertices() in WCS at angles in degrees
        if kind == "CIRCLE":
            return np.array(list(entity.vertices(np.linspace(0.0, 360.0, n))))
        a0, a1 = entity.dxf.start_angle, entity.dxf.end_angle
        a1 = a1 if a1 > a0 else a1 + 360.0
        return np.array(list(entity.vertices(np.linspace(a0, a1, n))))
    return np.array([tuple(v) for v in entity.flattening(0.001)]) if hasattr(entity, "flattening") else None


def closed(spline, points, degree, weights=None):
    if weights is None:
        spline.set_closed(points, degree=degree)
    else:
        spline.set_closed_rational(points, weights, degree=degree)
    return spline


@pytest.mark.parametrize("build", [
    lambda msp: msp.add_spline(fit_points=[(0, 0), (1, 1), (2, 0), (3, 1), (5, -2)]),
    lambda msp: msp.add_ellipse((1, 2), (3, 1), 0.4, start_param=0.3, end_param=4.0),
    lambda msp: msp.add_ellipse((0, 0, 0), (2, 0, 0), 0.5),
    lambda msp: closed(msp.add_spline(), [(0, 0, 0), (4, 0, 0), (5, 3, 0), (2, 5, 0), (-1, 3, 0)], degree=3),
    lambda msp: closed(msp.add_spline(), [(0, 0, 0), (4, 0, 0), (5, 3, 0), (2, 5, 0), (-1, 3, 0)], degree=2,
                       weights=[1, 2, 0.5, 1, 3]),
    lambda msp: msp.add_open_spline([(0, 0), (4, 0), (5, 3), (2, 5), (-1, 3)], degree=3),
    lambda msp: msp.add_arc((3, 4), 2.5, 200, 30),
], ids=["fit-points", "elliptic-arc", "ellipse", "closed-periodic", "closed-rational", "open-unclamped", "arc-wrapping"])
def test_entities_equal_ezdxfs_evaluation(tmp_path, build):
    """Each curve entity's path passes through ezdxf's own points within 1e-9 of its size."""
    doc, msp = drawing()
    entity = build(msp)
    file = tmp_path / "e.dxf"
    doc.saveas(file)
    (curve,) = load_dxf(file)
    pts = ezdxf_points(entity)[:, :2]
    size = np.max(np.ptp(pts, axis=0))
    assert np.max(distance_to([curve], pts)) <= 1e-9 * size
    # and the ends are ezdxf's ends
    np.testing.assert_allclose(curve(np.array([0.0, 1.0])), pts[[0, -1]], atol=1e-9 * size)


def test_r12_polyline_with_bulges_and_3d_entities(tmp_path):
    doc = ezdxf.new("R12")
    msp = doc.modelspace()
    msp.add_polyline2d([(0, 0, 0, 0, 1.0), (10, 0, 0, 0, 0), (10, 5)], format="xyseb")
    msp.add_line((10, 5, 0), (10, 5, 3))
    msp.add_polyline3d([(10, 5, 3), (12, 6, 4), (12, 6, 8)])
    file = tmp_path / "r12.dxf"
    doc.saveas(file)
    with pytest.warns(DxfWarning, match=r"declares no unit \(\$INSUNITS 0\); reading millimetres"):
        (c3,) = load_dxf(file, axes="xyz")
    assert c3.units == "mm" and c3.n_axes == 3
    half = math.pi * 5  # the bulge-1 segment: a half circle of diameter 10
    assert c3.length == pytest.approx(half + 5 + 3 + math.sqrt(5 + 1) + 4, rel=1e-12)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DxfWarning)
        with pytest.raises(PathFileError, match=r"LINE #\w+ is not flat: Z runs from 0 to 3; a machine with a Z axis"):
            load_dxf(file)


def test_degenerate_entities_are_skipped_and_annotations_warned_once_per_kind(tmp_path):
    doc, msp = drawing()
    for _ in range(300):
        msp.add_line((1, 1), (1, 1))
        msp.add_text("t")
    msp.add_mtext("m")
    msp.add_point((0, 0))
    msp.add_line((0, 0), (3, 4))
    file = tmp_path / "d.dxf"
    doc.saveas(file)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        (c,) = load_dxf(file)
    messages = [str(w.message) for w in caught if issubclass(w.category, DxfWarning)]
    assert c.length == pytest.approx(5.0, rel=1e-15)
    zero = [f"#{e.dxf.handle}" for e in msp if e.dxftype() == "LINE"][:3]
    handles = ", ".join(zero) + " and 297 more"
    assert sorted(m.split(": ", 1)[1] for m in messages) == [
        "1 MTEXT entity skipped (not a path)", "1 POINT entity skipped (not a path)",
        f"300 LINE entities of zero length skipped ({handles}), as CAD programs skip them",
        "300 TEXT entities skipped (not a path)"]
    assert all("\n" not in m for m in messages)


def test_corrupted_dxf_gives_one_line(tmp_path):
    doc, msp = drawing()
    msp.add_line((0, 0), (1, 1))
    file = tmp_path / "c.dxf"
    doc.saveas(file)
    text = file.read_text()
    cut = tmp_path / "cut.dxf"
    cut.write_text(text[: len(text) // 3])
    bad = tmp_path / "bad.dxf"
    bad.write_text(text.replace("AcDbLine\n 10\n", "AcDbLine\n 10\nnot-a-number\n", 1))
    for f in (cut, bad):
        try:
            load_dxf(f)
        except PathFileError as exc:
            assert "\n" not in str(exc) and str(exc).startswith(str(f))



def test_a_zero_radius_circle_is_skipped_and_a_negative_one_read_as_cad_does(tmp_path):
    """A CIRCLE or ARC of radius 0 is a point: skipped with one warning naming it, as CAD
    programs skip it, when the drawing has other contours; a CIRCLE's negative radius is
    read without its sign, as AutoCAD and ezdxf's own evaluation read it (issue 36)."""
    doc, msp = drawing()
    zero = msp.add_circle((5, 5), 0)
    zero_arc = msp.add_arc((7, 5), 0, 0, 90)
    negative = msp.add_circle((1, 0), -2)
    file = tmp_path / "r.dxf"
    doc.saveas(file)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        (c,) = load_dxf(file)
    messages = sorted(str(w.message) for w in caught if issubclass(w.category, DxfWarning))
    assert messages == sorted([
        f"CIRCLE #{negative.dxf.handle}: radius -2 read as 2 (CAD programs ignore the sign of a "
        "circle's radius)",
        f"{file}: 1 ARC entity of zero length skipped (#{zero_arc.dxf.handle}), as CAD programs skip them",
        f"{file}: 1 CIRCLE entity of zero length skipped (#{zero.dxf.handle}), as CAD programs skip them"])
    back = ezdxf.readfile(file)
    pts = ezdxf_points(back.entitydb[negative.dxf.handle], 64)[:, :2]
    assert np.max(distance_to([c], pts)) <= 1e-12
    assert c.length == pytest.approx(4 * math.pi, rel=1e-12)


def test_a_drawing_the_strict_reader_refuses_is_read_by_ezdxfs_recover_mode(tmp_path):
    """ezdxf's AC1003 example (R12 group codes out of order: 10, 11, 20, 21) is refused by
    ezdxf.readfile and read by ezdxf.recover.readfile; load_dxf reads it so, with one
    warning saying the drawing was repaired, to the same entities as recover's; a file cut
    short inside its entities (recover finds none) is still refused with the strict reason."""
    path = CORPUS / "ezdxf_AC1003_LINE_Example.dxf"
    with pytest.raises(ezdxf.DXFError):
        ezdxf.readfile(path)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        contours = load_dxf(path)
    repaired = [str(w.message) for w in caught if "recover" in str(w.message)]
    assert repaired == [f"{path}: the strict DXF reader refused the drawing (Missing required y "
                        "coordinate near line: 60.); read by ezdxf's recover mode, which repaired it "
                        "(0 audit fixes): check the contours, or save the drawing again from a CAD program"]
    doc, _ = ezdxf.recover.readfile(path)
    entities = [e for e in doc.modelspace()]
    assert len(entities) == 22
    pts = np.vstack([ezdxf_points(e, 50)[:, :2] for e in entities])
    assert np.max(distance_to(contours, pts)) <= 1e-12
    lengths = sum(np.linalg.norm(np.subtract(tuple(e.dxf.end), tuple(e.dxf.start))) if e.dxftype() == "LINE"
                  else math.radians((e.dxf.end_angle - e.dxf.start_angle) % 360) * e.dxf.radius
                  for e in entities)
    assert sum(c.length for c in contours) == pytest.approx(lengths, rel=1e-12)
    doc, msp = drawing()
    msp.add_line((0, 0), (1, 1))
    text = (tmp_path / "whole.dxf")
    doc.saveas(text)
    body = text.read_text()
    cut = tmp_path / "cut.dxf"
    cut.write_text(body[: body.index("AcDbLine") + 20])
    with pytest.raises(PathFileError, match=r"cannot read DXF: .*missing ENDSEC tag") as info:
        load_dxf(cut)
    assert "\n" not in str(info.value)

# ---------------------------------------------------------------- real-world drawings
CORPUS = __import__("pathlib").Path(__file__).resolve().parent / "data" / "corpus"
# "ok: axes" (loads on a machine with these axes) or the reason the file gives for a refusal
DXF_EXPECTED = {
    "bjnortier_circlesellipsesarcs.dxf": "ok: xy",
    "bjnortier_dimensions.dxf": "ok: xy",  # DIMENSION entities skipped with a warning
    "bjnortier_elliptical-arc1.dxf": "ok: xy",
    "bjnortier_ellipticalarcs.dxf": "ok: xy",
    "bjnortier_lwpolylines.dxf": "ok: xy",
    "bjnortier_splineA.dxf": "ok: xy",
    "bjnortier_splines.dxf": "ok: xy",
    "ezdxf_ASCII_R12.dxf": "ok: xy",  # an INSERT skipped with a warning
    "ezdxf_Leica_Disto_S910.dxf": "ok: xyz",  # 3-D lines from a laser meter
    "ezdxf_POLI-ALL210_12.DXF": "ok: xyz",  # R12 3-D polylines
    "ezdxf_AC1003_LINE_Example.dxf": "ok: xy",  # R12 group codes out of order: ezdxf's recover mode
    "ezdxf_circle_radius_le_0.dxf": "ok: xy",  # a CIRCLE of radius 0 skipped, one of -1 read as 1
}


@pytest.mark.parametrize("path", sorted(p for p in CORPUS.iterdir() if p.suffix.lower() == ".dxf"),
                         ids=lambda p: p.name)
def test_every_corpus_drawing_loads_or_is_refused_for_its_own_reason(path):
    expected = DXF_EXPECTED[path.name]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        if expected.startswith("ok: "):
            contours = load_dxf(path, axes=expected[4:])
            assert contours and all(c.length > 0 for c in contours)
            assert all(c.n_axes == len(expected[4:]) for c in contours)
        else:
            with pytest.raises(PathFileError, match=expected) as info:
                load_dxf(path)
            assert "\n" not in str(info.value)
    assert all("\n" not in str(w.message) for w in caught)


@pytest.mark.parametrize("path", sorted(p for p in CORPUS.iterdir() if p.suffix.lower() == ".dxf"
                                        and DXF_EXPECTED[p.name].startswith("ok")), ids=lambda p: p.name)
def test_corpus_entities_equal_ezdxfs_evaluation(path):
    """Every curve entity of the drawing lies on the read contours, within 1e-9 of the
    drawing size, at ezdxf's own points of it."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        axes = DXF_EXPECTED[path.name][4:]
        contours = load_dxf(path, axes=axes)
        try:
            doc = ezdxf.readfile(path)
        except ezdxf.DXFError:  # what load_dxf read through ezdxf's recover mode
            doc, _ = ezdxf.recover.readfile(path)
    size = max(np.max(np.ptp(c.control_points, axis=0)) for c in contours)
    size = max(size, max(np.max(np.abs(c.control_points)) for c in contours))
    worst = 0.0
    for e in doc.modelspace():
        if e.dxftype() not in ("SPLINE", "ELLIPSE", "ARC", "CIRCLE", "LINE"):
            continue
        if e.dxftype() in ("ARC", "CIRCLE") and e.dxf.radius == 0:  # a point, skipped
            continue
        pts = ezdxf_points(e, 50)[:, : len(axes)]
        worst = max(worst, float(np.max(distance_to(contours, pts))))
    assert worst <= 1e-9 * size


# ---------------------------------------------------------------- SPLINE repairs
NINE = [(0, 0), (1, 2), (3, 3), (4, 1), (6, 0), (7, 2), (8, 4), (10, 3), (11, 0)]
CLAMPED_KNOTS = [0, 0, 0, 0, 1, 2.5, 3, 4.5, 5, 7, 7, 7, 7]  # 13 = 9 + 3 + 1, non-uniform


def spline_file(tmp_path, name, knots, weights=None, points=NINE):
    doc, msp = drawing()
    s = msp.add_spline()
    s.dxf.degree = 3
    s.control_points = [(*p, 0) for p in points]
    s.knots = knots
    if weights is not None:
        s.weights = weights
    file = tmp_path / f"{name}.dxf"
    doc.saveas(file)
    return file


@pytest.mark.parametrize("name, knots, said", [
    ("first-missing", CLAMPED_KNOTS[1:], "the first knot repeated"),
    ("last-missing", CLAMPED_KNOTS[:-1], "the last knot repeated"),
    ("opennurbs", CLAMPED_KNOTS[1:-1], "the first and last knot repeated"),
])
def test_a_short_knot_vector_reads_as_the_full_one_ezdxf_evaluates(tmp_path, name, knots, said):
    doc, msp = drawing()
    full = msp.add_open_spline(NINE, degree=3, knots=CLAMPED_KNOTS)
    reference = ezdxf_points(full)[:, :2]
    file = spline_file(tmp_path, name, knots)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        (curve,) = load_dxf(file)
    messages = [str(w.message) for w in caught if issubclass(w.category, DxfWarning)]
    repairs = [m for m in messages if "knot vector" in m]
    assert len(repairs) == 1 and re.search(rf"SPLINE #\w+: knot vector has {len(knots)} entries, "
                                           rf"expected 13 = n \+ p \+ 1 \(9 control points, degree 3\); "
                                           rf"{said}", repairs[0])
    size = np.max(np.ptp(reference, axis=0))
    assert np.max(distance_to([curve], reference)) <= 1e-9 * size
    np.testing.assert_allclose(curve(np.array([0.0, 1.0])), reference[[0, -1]], atol=1e-9 * size)


def test_a_short_uniform_knot_vector_gets_its_last_knot_and_equals_ezdxf(tmp_path):
    uniform = list(range(13))  # unclamped, uniform: the end knots do not shape the curve
    doc, msp = drawing()
    full = msp.add_open_spline(NINE, degree=3, knots=uniform)
    reference = ezdxf_points(full)[:, :2]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        (curve,) = load_dxf(spline_file(tmp_path, "uniform", uniform[:-1]))
    messages = [str(w.message) for w in caught]
    assert sum("a last knot added at the same spacing" in m for m in messages) == 1
    assert sum("unclamped knot vector" in m for m in messages) == 1
    size = np.max(np.ptp(reference, axis=0))
    assert np.max(distance_to([curve], reference)) <= 1e-9 * size


def test_missing_weights_read_as_one_as_ezdxf_does(tmp_path):
    given = [1.0, 2.0, 0.5, 1.5]
    doc, msp = drawing()
    full = msp.add_rational_spline(NINE, given + [1.0] * 5, degree=3, knots=CLAMPED_KNOTS)
    reference = ezdxf_points(full)[:, :2]
    with pytest.warns(DxfWarning, match=r"SPLINE #\w+: 4 weights for 9 control points; the other 5 read as 1"):
        (curve,) = load_dxf(spline_file(tmp_path, "weights", CLAMPED_KNOTS, weights=given))
    size = np.max(np.ptp(reference, axis=0))
    assert np.max(distance_to([curve], reference)) <= 1e-9 * size


def test_a_knot_vector_short_at_an_unknown_end_is_refused_naming_the_entity(tmp_path):
    knots = [0, 0, 1, 2.5, 3, 4.5, 5, 6, 7, 8, 9, 9]  # 12: neither end says which is short
    with pytest.raises(PathFileError, match=r"SPLINE #\w+: knot vector has 12 entries, expected 13 "
                       r"= n \+ p \+ 1 \(9 control points, degree 3\), and which end lacks one"):
        load_dxf(spline_file(tmp_path, "unknown", knots))


# ---------------------------------------------------------------- chaining (issue 37)
def _chain_order_by_search(ends, tol):
    """The chaining as it was before the hash grid (every end searched at every step,
    quadratic), the reference :func:`nurbsmotion.paths.dxf._chain_order` must equal:
    per chain, (index, forward) from head to tail; ``ends`` row ``2 i`` is piece i's
    start, row ``2 i + 1`` its end."""
    starts, stops = ends[0::2], ends[1::2]
    used = np.zeros(len(starts), bool)
    chains = []
    for first in range(len(starts)):
        if used[first]:
            continue
        used[first] = True
        chain = [(first, True)]
        for at_tail in (True, False):
            while True:
                i, forward = chain[-1] if at_tail else chain[0]
                point = (stops if forward == at_tail else starts)[i]
                near_s = ~used & (np.linalg.norm(starts - point, axis=1) <= tol)
                near_e = ~used & (np.linalg.norm(stops - point, axis=1) <= tol)
                hit = np.flatnonzero(near_s | near_e)
                if hit.size == 0:
                    break
                i = int(hit[0])
                used[i] = True
                if at_tail:
                    chain.append((i, bool(near_s[i])))
                else:
                    chain.insert(0, (i, bool(near_e[i])))
        chains.append(chain)
    return chains


def _chain_by_search(pieces, tol):
    """:func:`_chain_order_by_search` on the pieces' end control points, each chain's
    pieces reversed where they run backwards."""
    ends = np.array([c.control_points[k] for c in pieces for k in (0, -1)])
    return [[pieces[i] if forward else pieces[i].reversed() for i, forward in chain]
            for chain in _chain_order_by_search(ends, tol)]


def _same_chains(a, b) -> bool:
    return [[(c.name, c.control_points.tobytes(), c.knots.tobytes(), c.weights.tobytes()) for c in chain]
            for chain in a] == [[(c.name, c.control_points.tobytes(), c.knots.tobytes(),
                                  c.weights.tobytes()) for c in chain] for chain in b]


def _random_drawing(seed: int, n_axes: int, n_pieces: int, tol: float) -> list:
    """Lines between a few shared nodes, shuffled, half of them reversed, each end on its
    node, or off it by exactly ``tol`` along an axis (rounding puts it on either side of
    the tolerance), by ``tol`` one ulp more or less, or by 2 ``tol``; some lines drawn
    twice (two pieces with the same ends)."""
    from nurbsmotion.nurbs import make_line

    rng = np.random.default_rng(seed)
    nodes = rng.uniform(-1.0, 1.0, (max(2, n_pieces // 2), n_axes)).round(rng.integers(1, 4))
    pieces = []
    for _ in range(20 * n_pieces):
        if len(pieces) >= n_pieces:
            break
        a, b = rng.choice(len(nodes), 2, replace=False)
        ends = []
        for node in (nodes[a], nodes[b]):
            p = node.copy()
            k = rng.integers(n_axes)
            p[k] += rng.choice([0.0, tol, -tol, np.nextafter(tol, 0), np.nextafter(tol, 1), 2 * tol])
            ends.append(p)
        if np.max(np.abs(ends[1] - ends[0])) < 1e-3:
            continue  # rounded nodes may coincide: no line (nor one of 1e-9 of the size)
        if rng.random() < 0.5:
            ends.reverse()
        for _ in range(1 + (rng.random() < 0.1)):
            pieces.append(make_line(*ends, name=f"L{len(pieces)}"))
    order = rng.permutation(len(pieces))
    return [pieces[i] for i in order]


@given(seed=st.integers(0, 2**32 - 1), n_axes=st.sampled_from([2, 3]),
       n_pieces=st.integers(1, 80), tol=st.sampled_from([0.0, 1e-9, 1e-3, 0.05]))
def test_chaining_by_the_grid_equals_the_search_it_replaces(seed, n_axes, n_pieces, tol):
    """The same pieces join, in the same order and direction (ties at a node: the lowest
    index first), ends at the tolerance included, as by the quadratic search."""
    from nurbsmotion.paths.dxf import _chain

    pieces = _random_drawing(seed, n_axes, n_pieces, tol)
    assert _same_chains(_chain(pieces, tol), _chain_by_search(pieces, tol))


@pytest.mark.parametrize("tol", [0.0, 1.0, 10.0, math.inf, math.nan])
def test_chaining_at_degenerate_tolerances_equals_the_search(tol):
    from nurbsmotion.paths.dxf import _chain

    pieces = _random_drawing(7, 2, 40, 1e-3)
    assert _same_chains(_chain(pieces, tol), _chain_by_search(pieces, tol))


@pytest.mark.parametrize("path", sorted(p for p in CORPUS.iterdir() if p.suffix.lower() == ".dxf"
                                        and DXF_EXPECTED[p.name].startswith("ok")), ids=lambda p: p.name)
def test_corpus_contours_are_those_of_the_search_chaining(path, monkeypatch):
    from nurbsmotion.paths import dxf

    axes = DXF_EXPECTED[path.name][4:]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        grid = dxf.load_dxf(path, axes=axes)
        monkeypatch.setattr(dxf, "_chain_order", _chain_order_by_search)
        search = dxf.load_dxf(path, axes=axes)
    assert len(grid) == len(search)
    assert all(a == b and a.name == b.name for a, b in zip(grid, search))


def test_a_line_flat_in_z_but_a_point_in_xy_is_named(tmp_path):
    """A LINE along Z shorter than the flatness test (1e-12) is flat, and a point in XY: cut
    to the machine's XY it is refused naming the entity, also when the axes are chosen from
    the drawing (it raised an untyped InvalidCurveError there before)."""
    doc, msp = drawing()
    msp.add_line((1, 0, 0), (2, 0, 0))
    line = msp.add_line((0, 0, 0), (0, 0, 1e-13))
    file = tmp_path / "needle.dxf"
    doc.saveas(file)
    for axes in ("xy", None):
        with pytest.raises(PathFileError, match=rf"LINE #{line.dxf.handle}: degenerate curve") as info:
            load_dxf(file, axes=axes)
        assert str(file) in str(info.value) and "\n" not in str(info.value)
    assert [c.n_axes for c in load_dxf(file, axes="xyz")] == [3, 3]
