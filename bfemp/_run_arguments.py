"""Checks of the arguments of ``Simulation`` and ``Simulation.run`` that need more than a type
test; each message names the argument as the user passed it (not an internal class)."""

from __future__ import annotations

__all__ = ["check_t_end"]


def check_t_end(t_end: float, t: float, dt: float, where: str | None = None) -> None:
    """Refuse a ``t_end`` (s) before the time ``t`` (s) a run starts from.

    A run to ``t_end == t`` (within ``1e-9 dt``) takes no step and is allowed.

    Args:
        t_end: the requested end time in s.
        t: the current time in s (after a resume: the checkpoint's).
        dt: the time step in s (scale of the tolerance).
        where: what ``t`` is, e.g. ``"the checkpoint in out/beam"``; default the current time.
    """
    if t_end < t - 1e-9 * dt:
        of = f"the time t = {t:.9g} s of {where}" if where else f"the current time t = {t:.9g} s"
        raise ValueError(
            f"Simulation.run: t_end = {t_end:.9g} s is earlier than {of}; give a t_end >= {t:.9g} s"
        )
