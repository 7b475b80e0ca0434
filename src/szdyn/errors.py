"""Exception types of szdyn.

Kept separate and tiny so every module (and the CLI) can import them without cycles.
"""


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


class UserInputError(ValueError):
    """Base class for mistakes in what the user supplied (CLI arguments, config files, data)."""


class ParameterError(UserInputError):
    """A model parameter is missing, unknown, non-finite or outside its physical range."""
