"""G-code import (LinuxCNC and Fanuc NURBS dialects) and G5.2 export of a path.

Reading
-------
:func:`load_gcode` reads the motion of a program along the path axes and returns a
:class:`GcodeProgram`: the *contours* it cuts, each one :class:`NurbsCurve` joined from
the program's feed moves (as :func:`nurbsmotion.joining.join` joins pieces, built in bulk
by :class:`~nurbsmotion.paths.pieces.PieceChain`), plus the programmed feed of every piece.

Size
    Plain lines (words and comments, as CAM posts write them) are tokenised for the whole
    program at once (:class:`~nurbsmotion.paths.gcode.ngc.WordTable`: one multi-line regular
    expression search, then numpy), and each run of them is applied in bulk where
    :meth:`reader._Reader.read` would take its lean path (G0/G1 moves and F words under G90/G94,
    no offsets): the same pieces, feeds, lines and errors as one line at a time. A move
    costs a few numbers until its contour is joined: a CAM program of a million lines
    loads in a few seconds and about half a gigabyte (``benchmarks/gcode_load.py``).
    ``run`` and ``bound`` first read only a program's first lines (by the same reader,
    :mod:`~nurbsmotion.paths.gcode.first_part`) and refuse, without reading the rest, a
    program whose first lines already hold more sharp corners than the planner's grid.

What is read
    The language (parameters, expressions, O-word subroutines and control flow) is
    executed by :mod:`nurbsmotion.paths.gcode.ngc`; the reader turns the executed blocks into
    motion, in LinuxCNC's canonical coordinates (G5x + G92 offsets and the XY rotation of
    ``G10 L2 R`` applied, as AXIS draws them): ``G0`` and ``G1``; ``G2``/``G3`` in the
    G17/G18/G19 plane in centre format (incremental, or absolute under ``G90.1``) or radius
    format, with ``P`` turns, as exact rational arcs, as a helix (cubic segments within
    :data:`HELIX_TOLERANCE` of the radius, :func:`~nurbsmotion.paths.pieces.spiral_segments`)
    when another axis moves along, or as a spiral
    when the end radius differs from the start radius by more than :data:`HELIX_TOLERANCE`
    of it (and within LinuxCNC's tolerance); ``G5``
    and ``G5.1`` (XY); ``G5.2``/``G5.3`` and ``G6.2`` (``P`` order, ``Q`` method, ``K``
    knots, ``R`` weights; Fanuc ``G06.2`` alike) in the XY, YZ and ZX planes; ``F`` under
    ``G94`` (units per minute) or ``G93`` (inverse time); ``G20``/``G21``; ``G90``/``G91``;
    ``G53``; ``G54``-``G59.3``; ``G10 L2/L20``; ``G92``, ``G92.1``/``.2``/``.3``;
    ``G28``/``G30`` (a rapid through the given point to the stored home: a new contour);
    polar ``@``/``^``; the canned cycles ``G73``, ``G74``, ``G81``-``G89`` with ``G98``/``G99``,
    ``L`` repeats, incremental and polar positions, in the three planes, expanded into G0
    and G1 moves as LinuxCNC's ``interp_cycles.cc`` does (:meth:`cycles._Cycles.canned_cycle`:
    each feed move along the depth axis a piece of a contour, every rapid, reversal or
    dwell the end of one), ``G80``. Words that do not change the path are skipped, each
    kind reported once as a :class:`GcodeWarning` (one line). ``M2``/``M30`` end the
    program; ``G4`` (dwell) ends the contour. What would change the path but is not read
    (the G76 threading cycle, spindle-synchronised motion, probing, UVW planes, cutter
    compensation in G19) is a :class:`PathFileError` naming the line. Cutter compensation
    (G40-G42.1) is computed as LinuxCNC's interpreter does (:mod:`.compensation`).

Contours
    The machine's axes decide which coordinates form the path (``axes``, default
    ``"xy"``). A contour is a maximal run of feed moves of those axes; a rapid move, or a
    move of an axis outside the path, ends it. A feed move of an outside axis together with
    path axes (a helix on a 2-axis machine, a rotary axis) is refused, naming the machine
    that could follow it. :func:`nurbsmotion.paths.resolve_path` asks the user to pick one
    contour (``file.ngc#k``) when there are several, rather than guessing. A G0/G1 move of
    the path axes shorter than :data:`~nurbsmotion.paths.gcode.codes.MIN_MOVE` (1e-12) is
    dropped, as LinuxCNC's planner drops it; the position still moves. Rotary axes A, B, C
    are read in degrees; a run on a machine that has them scales them by its pulses per
    degree, with LinuxCNC's feed rule (:mod:`nurbsmotion.run_input`).

LinuxCNC G5.2 (2.9, read from ``interp_convert.cc`` and ``nurbs_additional_functions.cc``)
    The current position is the first control point; ``G5.2 P-`` without X/Y sets its
    weight (a first listed point equal to it repeats it: C'(0) = 0, kept as given). Every later point needs X, Y and a positive P. ``L`` sets the order only when
    ``L > 3`` (default 3, i.e. quadratic). The knot vector is implicit and open-uniform
    over integers: ``k`` zeros, ``1 .. n-k+1``, ``k`` times ``n-k+2`` for ``n + 1``
    control points of order ``k`` (``knot_vector_creator``). Under ``G91`` every control
    point is relative to the position *before the block*. Z words inside the block are
    ignored (with a warning). X/Y on the opening line without P: the manual says weight 1,
    the 2.9 interpreter stores -1; this reader follows the manual and warns. The feed is
    the one in force at ``G5.3``, where LinuxCNC issues the move.

Fanuc G06.2
    ``G06.2 P<order> K<knot> X.. Y.. R<weight> F..`` then one ``K X Y [R]`` block per
    control point and ``order`` blocks of ``K`` only; the knot count must equal control
    points + order and the first and last ``order`` knots must be equal (clamped ends).
    P defaults to 4, R to 1. Without X/Y in the first block the current position is the
    first control point; if given, it must be the current position.

Writing
-------
:func:`save_gcode` writes a path as a LinuxCNC program of ``G5.2`` blocks. Since a G5.2
knot vector is implicit and uniform, the path is split into its rational Bézier segments
(exactly representable: order ``p + 1``, ``p + 1`` points, knots ``0..0 1..1``); degree-1
paths are first elevated to 2, the lowest order G5.2 accepts. Reading the file back gives
the same geometry to 1e-9 of the path size (the numbers are written with 12 significant
digits relative to the path size).

Glossary
--------
k : NURBS order (degree + 1); n + 1 : number of control points; w : weight;
F : programmed feed [units/min]; feed : F / 60 [units/s].

Modules
-------
``ngc``      the RS274/NGC language (tokenizer, expressions, parameters, O-words)
``program``  what is read: GcodeProgram, GcodeContour, GcodeWarning
``codes``    the G/M codes, words and limits read, as tables
``reader``   the motion layer (``_Reader``: modal state, moves, contours) and load_gcode
``frames``   G5x/G92 offsets and rotation: program <-> absolute coordinates
``curves``   G2/G3 arcs and helices, G5/G5.1, G5.2/G5.3 and G6.2 NURBS blocks
``cycles``   the canned cycles G73, G74, G81-G89
``bulk``     runs of plain lines applied in bulk
``first_part``  a program's first lines read alone, for a size refusal before the whole
``writer``   save_gcode (G5.2 export) and number formatting
"""

from .curves import linuxcnc_knots
from .ngc import MAX_LINE_LENGTH
from .program import GcodeContour, GcodeProgram, GcodeWarning
from .reader import load_gcode
from .writer import decimals_for, format_number, save_gcode

__all__ = [
    "GcodeContour",
    "GcodeProgram",
    "GcodeWarning",
    "load_gcode",
    "save_gcode",
    "linuxcnc_knots",
    "format_number",
    "decimals_for",
    "MAX_LINE_LENGTH",
]
