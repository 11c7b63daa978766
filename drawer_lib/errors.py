"""The project's exceptions, in one place.

::

    DrawerError                      everything the library raises on purpose
    ├── InputError (ValueError)      bad input a user can cause: a file, a capture, a config value
    │   ├── ConfigError              a config key or value is missing, unknown or out of range
    │   └── CaptureError             a capture folder, image, depth map, detection or parts file
    ├── NonFiniteError (ArithmeticError)   a NaN or inf reached a place it must not pass
    └── InvariantError (RuntimeError)      a result broke a guarantee of the method (a bug)
        └── TwinCheckError                 a built twin fails a physical check (names the part)

Stage entry points (:func:`drawer_lib.runner.main_guard`) turn an :class:`InputError` into one
line, ``error: <message>``, and exit code 2; the message names the file, frame or key. The other
two are failures of the computation, not of the input: they end the stage with a traceback and
exit code 1. Contract violations of library functions by their callers (wrong shapes, dtypes)
stay plain ``ValueError`` / ``TypeError``, as in numpy and torch.
"""


class DrawerError(Exception):
    """Base of the exceptions this library raises on purpose."""


class InputError(DrawerError, ValueError):
    """Bad input (file, config value, capture). The message names what is wrong."""


class ConfigError(InputError):
    """A config value is missing, unknown or out of range (the message names the key path)."""


class CaptureError(InputError):
    """Bad capture input. The message names the offending file, frame or value."""


class NonFiniteError(DrawerError, ArithmeticError):
    """A NaN or inf reached a place where it must not travel further (the message names it)."""


class InvariantError(DrawerError, RuntimeError):
    """A result violates a guarantee of the method (e.g. a Gaussian outside its face bounds)."""


class TwinCheckError(InvariantError):
    """A built twin fails a physical check (a part that does not open or passes its limit, a
    penetration, an object that does not rest). The message names every failing part;
    ``failures`` lists ``{"id", "check", "message"}`` and ``report`` holds what was measured."""

    def __init__(self, message: str, failures: list[dict] | None = None, report: dict | None = None):
        super().__init__(message)
        self.failures = list(failures or [])
        self.report = report
