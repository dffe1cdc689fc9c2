"""The Robotarium toolbox: what `from rps.utilities.X import *` brings into an experiment script.

  transformations (guide 4.3), controllers (4.4), barrier_certificates and barrier_certificates2
  (4.5, 4.6; robotarium_safety), misc (initial conditions, "at goal" tests, plot sizes: 4.7),
  graph (Laplacians and neighbours: 4.8)

Names, parameters and defaults are those of the Robotarium's own simulator (robotarium-python-
simulator 0.0.0, "rps") and the guide; where rps has a bug, the fix is marked next to the code.
This file also holds the argument checks the modules share: they raise RobotariumError (a
ValueError and an AssertionError) naming the function, the argument, what was expected and what
was received; underscore names, so star imports never bring them.
"""
import numbers

import numpy as np

from robotarium_core.model import RobotariumError


def _describe(value):
    """A short description of a received value for an error message."""
    if isinstance(value, np.ndarray):
        return "a %s array of shape %s" % (value.dtype, value.shape)
    if isinstance(value, (bool, np.bool_, numbers.Number, str)) or value is None:
        return repr(value)
    if isinstance(value, (list, tuple)) and len(repr(value)) <= 60:
        return "%s %r" % (type(value).__name__, value)
    return "a value of type %s" % type(value).__name__


def _check_number(value, name, where, *, low=None, strict=False, high=None, allow_inf=False,
                  integer=False):
    """Return `value` as a Python number after checking its type, finiteness and range.

    low/high: inclusive bounds (low exclusive when strict=True); allow_inf lets +inf through
    (for limits where it means "no limit"); integer asks for an int (numpy ints welcome).
    Booleans are refused: True as a gain or a count is a slip, not an intent.
    """
    kind = "an integer" if integer else "a number"
    if isinstance(value, (bool, np.bool_)) or not isinstance(
            value, numbers.Integral if integer else numbers.Real):
        raise RobotariumError("%s: %s must be %s; received %s." % (where, name, kind, _describe(value)))
    if integer:
        value = int(value)
    else:
        value = float(value) if not isinstance(value, numbers.Integral) else int(value)
        if np.isnan(value) or (np.isinf(value) and not (allow_inf and value > 0)):
            raise RobotariumError("%s: %s must be a finite number%s; received %r."
                                  % (where, name, " (or +inf for no limit)" if allow_inf else "", value))
    too_low = low is not None and (value <= low if strict else value < low)
    too_high = high is not None and value > high
    if too_low or too_high:
        if low is not None and high is not None:
            expected = "in %s%r, %r]" % ("(" if strict else "[", low, high)
        elif low is not None:
            expected = "%s %r" % (">" if strict else ">=", low)
        else:
            expected = "<= %r" % (high,)
        raise RobotariumError("%s: %s must be %s %s; received %r." % (where, name, kind, expected, value))
    return value


def _check_array(value, name, where, rows, columns=None, what=""):
    """Return `value` as a 2-D float64 array with `rows` rows and finite entries.

    rows: the required number of rows (None: any); columns: the required number of columns
    (None: any; it is how a function makes its arrays agree on N); what: the meaning of the rows,
    for the message, e.g. "[x; y; theta]". Like rps, only numpy arrays are accepted (np.matrix is
    turned into a plain array, so its 2-D row indexing cannot leak into the maths).
    """
    shape_text = "%sx%s" % (rows if rows is not None else "M", columns if columns is not None else "N")
    expected = "a %s numpy array%s" % (shape_text, (" " + what) if what else "")
    if not isinstance(value, np.ndarray):
        raise RobotariumError("%s: %s must be %s; received %s." % (where, name, expected, _describe(value)))
    if value.dtype.kind not in "biuf":
        raise RobotariumError("%s: %s must be %s of numbers; received %s."
                              % (where, name, expected, _describe(value)))
    if value.ndim != 2 or (rows is not None and value.shape[0] != rows) or (
            columns is not None and value.shape[1] != columns):
        raise RobotariumError("%s: %s must be %s; received an array of shape %s."
                              % (where, name, expected, value.shape))
    array = np.asarray(value, dtype=np.float64)
    if not np.all(np.isfinite(array)):
        bad = sorted(set(np.nonzero(~np.isfinite(array))[1].tolist()))
        raise RobotariumError("%s: %s must hold finite numbers only; received NaN or inf in column(s) %s."
                              % (where, name, bad))
    return array
