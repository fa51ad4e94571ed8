"""Errors raised for bad user input, carrying where the mistake is.

:class:`SceneError` is a ``ValueError`` (so code that catches ``ValueError`` keeps working) that
also records the scene file, the body and the field at fault, and a suggested fix. Its message
reads, for example::

    examples/beam.toml: fem body 'beam': material.nu: must be < 0.5, got 0.5 (hint: nu >= 0.5
    is incompressible, which these materials cannot represent; use nu <= 0.49)

The command line prints that message after ``bfemp: error:`` without a traceback.
"""

from __future__ import annotations

import logging
import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from contextvars import ContextVar

__all__ = [
    "BfempWarning",
    "PlausibilityWarning",
    "RunFolderError",
    "SceneError",
    "StepNoteWarning",
    "collect_warnings",
    "note_name",
    "warn_user",
]

log = logging.getLogger("bfemp")


class SceneError(ValueError):
    """A mistake in a scene (file or API call), located by file, body and field.

    Args:
        message: what is wrong (without the location).
        file: the scene file (or the API argument) in which the mistake is, if any.
        body: kind and name of the body at fault, e.g. ``"fem body 'beam'"``, if any.
        field: the key path of the field at fault, e.g. ``"material.nu"``, if any.
        hint: how to fix it, when that is obvious.
    """

    def __init__(
        self,
        message: str,
        *,
        file: str | None = None,
        body: str | None = None,
        field: str | None = None,
        hint: str | None = None,
    ) -> None:
        self.message = str(message)
        self.file = None if file is None else str(file)
        self.body = body
        self.field = field
        self.hint = hint
        super().__init__(self._format())

    def _format(self) -> str:
        parts = [p for p in (self.file, self.body, self.field) if p]
        text = ": ".join([*parts, self.message])
        if self.hint:
            text += f" (hint: {self.hint})"
        return text

    def located(self, *, file: str | None = None) -> SceneError:
        """A copy with the file set (when it was not known where the error was raised)."""
        return SceneError(
            self.message,
            file=self.file if self.file is not None else file,
            body=self.body,
            field=self.field,
            hint=self.hint,
        )


class RunFolderError(SceneError):
    """A run folder that cannot be written or continued: in use by another run, a file where
    the folder should be, or a corrupt checkpoint, manifest or frame.

    ``file`` is the path at fault (the folder, or the file in it); the message says what is
    wrong with it and the hint how to go on. A :class:`SceneError` (and so a ``ValueError``):
    the command line prints it after ``bfemp: error:`` and exits with status 2.
    """


class BfempWarning(UserWarning):
    """What bfemp tells the user to act on or to know (:func:`warn_user`): a setting that is
    not used, a grid that does not fit the mesh, an output file not written, ...

    The message starts with a name in capitals followed by a colon (``P2G_ZERO_MASS: ...``).
    ``warnings.simplefilter("ignore", bfemp.BfempWarning)`` silences all of them.
    """


class StepNoteWarning(BfempWarning):
    """What a run noticed and the user should see: a step's named note (``INTERPENETRATION``,
    ``LR_UNCONVERGED``, ...), an energy growth, a pair of bodies the strategy does not couple.

    The message starts with the note's name in capitals followed by a colon.
    """


class PlausibilityWarning(StepNoteWarning):
    """A discretisation or a run outside the ranges where its results are plausible: particles
    per grid cell, grid cells across an MPM body, dt against a body's wave period
    (``IMPLAUSIBLE_GRID``, ``IMPLAUSIBLE_DT``, at construction) or a closed scene that loses most
    of its energy (``ENERGY_LOSS``, once per run). Thresholds: :mod:`bfemp.plausibility`.

    A ``StepNoteWarning``, so that filters on that category (and the command line, which logs
    these once) treat it the same; filter this class alone to silence only these notes.
    """


#: the receiver of :func:`warn_user` while a simulation works (``Simulation`` sets it)
_SINK: ContextVar[Callable[[str, type, logging.Logger], None] | None] = ContextVar(
    "bfemp_warning_sink", default=None
)


def warn_user(
    message: str,
    *,
    category: type[Warning] = BfempWarning,
    logger: logging.Logger | None = None,
    stacklevel: int = 2,
) -> None:
    """Tell the user ``message`` (``"NAME: text"``): something to act on or to know.

    Inside a simulation's work (its construction, ``step``, ``run``, ``load_checkpoint``: the
    simulation collects through :func:`collect_warnings`) the warning is counted in
    ``sim.note_counts`` by its name, and only the first of each name in a simulation is kept in
    ``sim.diagnostics``, logged and issued through Python's ``warnings`` as ``category``.
    Elsewhere it is logged (``logger``, else ``bfemp``) and issued every time (Python's default
    filter shows an identical message from one place once).

    Python's ``warnings`` reach a plain script without any logging set up (the package logger
    has a ``NullHandler``, so its records alone would not); the log line serves the command
    line and log files. Internal detail stays ``logging`` only.
    """
    sink = _SINK.get()
    if sink is not None:
        sink(message, category, logger or log)
        return
    (logger or log).warning("%s", message)
    warnings.warn(message, category, stacklevel=stacklevel + 1)


@contextmanager
def collect_warnings(sink: Callable[[str, type, logging.Logger], None]) -> Iterator[None]:
    """Send :func:`warn_user` calls to ``sink(message, category, logger)`` within the block
    (nested blocks: the innermost sink)."""
    token = _SINK.set(sink)
    try:
        yield
    finally:
        _SINK.reset(token)


def note_name(note: str) -> str:
    """The name of a named note ``"NAME: text"`` (the whole note when it has no colon)."""
    return note.split(":", 1)[0].strip()
