"""Write examples/helix3d.json: a 3-axis path in mm for examples/gantry3.toml.

A 5 mm vertical plunge, then a sharp corner into 1.5 turns of a helix (radius 10 mm,
pitch 4 mm, going down) fitted by a cubic B-spline through 49 points. Run it with

    nurbsmotion run examples/helix3d.json --machine examples/gantry3.toml --feed 50mm/s --out out/helix
"""

from pathlib import Path

import numpy as np
from scipy.interpolate import make_interp_spline

import nurbsmotion as nm
from nurbsmotion.joining import join

RADIUS, PITCH, TURNS = 10.0, 4.0, 1.5  # [mm], [mm per turn], [1]


def helix3d() -> nm.NurbsCurve:
    angle = np.linspace(0.0, 2 * np.pi * TURNS, 49)
    points = np.column_stack([RADIUS * np.cos(angle), RADIUS * np.sin(angle),
                              -PITCH * angle / (2 * np.pi)])
    spline = make_interp_spline(angle / angle[-1], points, k=3)
    helix = nm.NurbsCurve(3, spline.t, spline.c, units="mm")
    plunge = nm.make_line([RADIUS, 0.0, 5.0], [RADIUS, 0.0, 0.0], units="mm")
    return join([plunge, helix], name="helix3d")


if __name__ == "__main__":
    nm.save_path(helix3d(), Path(__file__).with_name("helix3d.json"), overwrite=True)
