"""Errors the toolkit raises on bad input; the CLI prints them as one line, without a traceback."""

#: exit status of an internal error (a bug, not bad input): sysexits' EX_SOFTWARE, apart from 1 (the
#: data), 2 (usage), 3 (a stopped admittance run), 4 (with --strict, a run-admittance or validate that
#: warned), 130 and 141 (signals)
EXIT_INTERNAL = 70


class KukaidError(Exception):
    """Base class: a problem the user can fix, described in one line.

    ``exit_code`` is the command's exit status: 1 for a problem found in the data (a log, a
    parameter file, the controller), 2 for a usage error (:class:`OptionError`)."""

    exit_code = 1


class OptionError(KukaidError):
    """A usage error the library finds: options that contradict each other or the data given
    (no --axis for a log of several axes, options that apply only without another).  Exit status 2."""

    exit_code = 2


class LogFormatError(KukaidError):
    """An axis log (CSV, HDF5, MAT, Trace) is malformed or inconsistent."""


class TrajectoryError(KukaidError):
    """A trajectory file or a generator option is malformed or out of range."""


class ParamFileError(KukaidError):
    """A parameter file is missing a field, has a wrong type or an out-of-range value."""


class SimConfigError(ParamFileError):
    """A simulator configuration has an unknown field, a wrong type or an out-of-range value."""


class LimitError(KukaidError):
    """A trajectory or command breaks a position, velocity, acceleration or torque limit."""


class FitError(KukaidError):
    """Identification could not produce trustworthy parameters (no data, failed solve, ...)."""


class ControllerError(KukaidError):
    """A robot controller (real or virtual) did not answer, answered wrongly, or went stale."""


class DiskFullError(KukaidError):
    """The disk (or the file-size limit) leaves too little room to go on recording safely."""
