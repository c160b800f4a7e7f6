"""The RS274/NGC language layer moved to :mod:`nurbsmotion.paths.gcode.ngc` (issue 31); this
module keeps the old import path working and re-exports its public names."""

from .gcode.ngc import (MAX_CALL_DEPTH, MAX_EXTRA_BLOCKS, MAX_LINE_LENGTH, MAX_NUMBER_CHARS, Block,
                        Program, Rows, WordTable, split_lines)

__all__ = ["Block", "Rows", "WordTable", "Program", "split_lines", "MAX_NUMBER_CHARS", "MAX_CALL_DEPTH",
           "MAX_EXTRA_BLOCKS", "MAX_LINE_LENGTH"]
