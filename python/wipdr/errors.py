"""Exceptions raised by wipdr.

Every error of the Rust library reaches Python as one of these, with the Rust error's
message (naming the file, line, field or config path):

- :class:`DataError` (an :class:`OSError`): a file or folder could not be read, or its
  content broke the format or a reader's limit.
- :class:`ConfigError` (a :class:`ValueError`): a config could not be read (unknown field,
  bad value; the message names the field's path), or a mode this build lacks.
- :class:`InputError` (a :class:`ValueError`): bad arguments from Python (array shapes,
  non-finite values, bad BSSIDs, unknown schemes), or an evaluation that cannot run on
  the data given (too few walks for the folds, nothing scored).

All three are :class:`WipdrError`, so ``except wipdr.WipdrError`` catches any of them.
"""


class WipdrError(Exception):
    """Base class of every wipdr error."""


class DataError(WipdrError, OSError):
    """A file or folder could not be read, or broke the format or a reader's limit."""


class ConfigError(WipdrError, ValueError):
    """A config could not be read or has a bad value; the message names the field."""


class InputError(WipdrError, ValueError):
    """Bad arguments or data from Python, or an evaluation that cannot run on them."""


__all__ = ["WipdrError", "DataError", "ConfigError", "InputError"]
