"""From a machine's own log to its machine file: identification and excitation.

:func:`read_log` reads a log (CSV with a header, or the project's ``trace.csv`` /
``trace.parquet``): time, and per axis the drive [V] and the encoder's reading.
:func:`identify` fits each axis to the real-machine plant of issue 32 (time constant,
gain, delay, Coulomb friction, stiction, and a mode where the data show one) and returns
an :class:`Identification`: per parameter the estimate, its standard deviation, the fit's
residual, and what the log cannot identify and why. :meth:`Identification.to_machine_dict`
is the machine file, with the gains of a base machine (identification never invents a
controller). :func:`excitation` makes a short drive sequence that makes every parameter
identifiable within the machine's limits, and :func:`excitation_gcode` its variant of
position moves. The method is in docs/identify.md.

The subpackage's modules: :mod:`.log` (reading a log), :mod:`.identification`
(:func:`identify` and its result), :mod:`.excite` (the test move), :mod:`.fit` (fitting one
axis), :mod:`.model` (the fitted model, simulated exactly) and :mod:`.plot` (the figure;
output layer, reached only through :meth:`Identification.plot`).

Only Ke*Kc is seen in a log of drive and position; Ke comes from the base machine and Kc is
the product divided by it.

Glossary
--------
tau : time constant [s]; Kc : electrical gain [(rad/s)/V]; Ke : mechanical gain
[pulse/rad]; G = Ke*Kc : speed per volt [pulse/s/V]; Ts : sample period [s]; u : drive
[V]; y : encoder reading [pulse].
"""

from .excite import DEFAULT_TRAVEL_MM, excitation, excitation_gcode, write_excitation_csv
from .identification import (DEFAULT_MECHANICAL_GAIN, TAU_SPREAD, AxisIdentification,
                             Estimate, Identification, identify, write_identification)
from .log import (DRIVE_SUFFIXES, LOG_UNITS, MAX_JITTER, POSITION_SUFFIXES, TIME_UNITS,
                  Log, log_from_arrays, read_log)

__all__ = ["Log", "read_log", "log_from_arrays", "Estimate", "AxisIdentification",
           "Identification", "identify", "excitation", "excitation_gcode",
           "write_excitation_csv", "write_identification", "POSITION_SUFFIXES",
           "DRIVE_SUFFIXES", "LOG_UNITS", "TIME_UNITS", "MAX_JITTER", "TAU_SPREAD",
           "DEFAULT_MECHANICAL_GAIN", "DEFAULT_TRAVEL_MM"]
