"""The error an argument out of its valid range raises, naming the argument.

A function that checks its arguments (a mould's shape, a distribution's parameters, a
random field's correlation) raises :class:`ParameterError` with the names of the
arguments at fault as it spells them. A caller that knows where each argument came from
-- the study validator knows the study-file key of every one -- blames that key from
``names``, never by reading the message; the command line turns ``names`` into its flags.
An error that is not about a bad value (a busy or damaged run folder, an OSError) names
the arguments that would get past it with :func:`naming`. This module imports nothing.
"""

from __future__ import annotations


class ParameterError(ValueError):
    """A bad argument value. ``names``: the arguments at fault (a tuple, possibly empty)."""

    def __init__(self, names, message: str):
        super().__init__(message)
        self.names = (names,) if isinstance(names, str) else tuple(names)


def naming(err: BaseException, *names: str) -> BaseException:
    """``err`` carrying ``names`` (as :class:`ParameterError` does): the arguments that
    would get past it, e.g. ``resume`` for a run folder that cannot be resumed."""
    err.names = names
    return err
