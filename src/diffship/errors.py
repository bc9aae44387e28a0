"""Exceptions raised by diffship.

Every error diffship raises on bad input is a :class:`DiffshipError`. Its message is meant
for a person: it names the file, run, column or parameter at fault and says what to do.
The command-line tools print the message on one line and exit with status 2, without a
traceback.
"""


class DiffshipError(Exception):
    """Base class of every error diffship raises on purpose."""


class DataError(DiffshipError, ValueError):
    """A run, file or column is unusable as given (wrong order, NaN, units, missing, ...)."""


class ModelError(DiffshipError, ValueError):
    """A model or parameter specification is inconsistent (unknown name, bad bounds, ...)."""


class FitError(DiffshipError, RuntimeError):
    """A fit could not be carried out (e.g. the model diverges from every start)."""
