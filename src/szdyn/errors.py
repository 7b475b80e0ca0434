"""Exception types of szdyn.

Kept separate and tiny so every module (and the CLI) can import them without cycles.
"""


def brief(value) -> str:
    """``repr(value)``, except that an integer of more than 15 digits is shown by its first digits
    and its length: an error message does not echo a 400-digit input back in full."""
    if isinstance(value, int) and not isinstance(value, bool):
        text = str(abs(value))
        if len(text) > 15:
            return f"{'-' if value < 0 else ''}{text[:6]}... (an integer of {len(text)} digits)"
    return repr(value)


class SimulationError(RuntimeError):
    """The integration could not continue (non-finite state, step-size underflow, step limit).

    The message says when (t in s), which state variable, and what to try next. Extra context is
    available as attributes: ``t`` (s), ``variable`` (name or None), ``trajectory`` (the
    :class:`szdyn.integrators.Trajectory` saved up to the failure, or None).
    """

    def __init__(self, message, *, t=None, variable=None, trajectory=None):
        super().__init__(message)
        self.t = t
        self.variable = variable
        self.trajectory = trajectory


class Terminated(KeyboardInterrupt):
    """SIGTERM received by a command (:func:`szdyn.processes.sigterm_as_interrupt`): handled as
    Ctrl-C is, so that what finished is saved and the command says how to resume."""


class UserInputError(ValueError):
    """Base class for mistakes in what the user supplied (CLI arguments, config files, data)."""


class ParameterError(UserInputError):
    """A model parameter is missing, unknown, non-finite or outside its physical range."""


def interrupted(exc: BaseException) -> bool:
    """True for Ctrl-C: a :class:`KeyboardInterrupt`, or the :class:`SystemError` ("returned a
    result with an exception set") CPython raises, with the interrupt as its cause, when Ctrl-C
    lands while a compiled (Numba) function returns."""
    while exc is not None:
        if isinstance(exc, KeyboardInterrupt):
            return True
        if not isinstance(exc, SystemError):
            return False
        exc = exc.__cause__ or exc.__context__
    return False
