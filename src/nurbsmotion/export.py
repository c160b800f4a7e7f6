"""The old path of :mod:`nurbsmotion.report.export` (issue 31): it re-exports the public
names, so ``from nurbsmotion.export import save_setpoints`` keeps working."""

from .report.export import (  # noqa: F401
    QUDT_UNITS,
    CsvColumn,
    ExportError,
    metadata_file,
    save_csv_metadata,
    setpoint_columns,
    PvtTable,
    SetpointArrays,
    decimals_for_resolution,
    pvt_table,
    save_halstreamer,
    save_motion_gcode,
    save_pvt,
    save_ros_trajectory,
    save_setpoints,
)
from .report.export import __all__  # noqa: F401
