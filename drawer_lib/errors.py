"""Project exceptions. Bad input is an :class:`InputError` whose message names the file or value;
stage entry points turn it into a one-line message and exit code 2 (see :mod:`drawer_lib.runner`)."""


class InputError(ValueError):
    """Bad input (file, config value, capture). The message names what is wrong."""


class ConfigError(InputError):
    """A config value is missing, unknown or out of range."""


class NonFiniteError(ArithmeticError):
    """A NaN or inf reached a place where it must not travel further (the message names it)."""
