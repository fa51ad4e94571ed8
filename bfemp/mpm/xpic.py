"""Multimaterial XPIC(m) (LR section 3.3, LR eqs. 35-47).

With A_a = S+^a S (G2P to the particles of material a, then P2G with the masses m^a), the
projected particle velocity of LR eq. 37, rewritten by push-through, is P V^n = S v*^a with

    v*^a = sum_{k=0}^{m-1} (I - A_a)^k v^a  -  sum_{k=0}^{m-2} (I - A_a)^k dv^a

where v^a are the grid velocities after the first contact correction and dv^a that correction
(``"paper"``, LR eqs. 41-44). m = 1 gives S v^a, PIC (LR eq. 38); m = 2 gives LR eq. 46. The
variants of
the paper's comparison: ``"uncorrected"`` starts from the P2G velocities v^{a0} and has no dv term
(Fig. 7); ``"corrected_velocity"`` starts from v^a without the dv term (Uintah's XPIC2; its
perfect-interface error is LR eq. 48).

The loop costs 2m - 3 applications of A (m >= 2; m - 1 without the dv term), each one G2P and
one P2G over every material at once (each particle transfers only to its own material's field).
Prescribed components of every increment are removed by ``project`` (NairnMPM zeroes them at
boundary-condition nodes).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

__all__ = ["XPIC_VARIANTS", "xpic_grid_velocity"]

XPIC_VARIANTS = ("paper", "uncorrected", "corrected_velocity")


def xpic_grid_velocity(
    order: int,
    variant: str,
    v: np.ndarray,
    v_p2g: np.ndarray,
    dv: np.ndarray,
    apply_A: Callable[[np.ndarray], np.ndarray],
    project: Callable[[np.ndarray], np.ndarray] | None = None,
) -> np.ndarray:
    """The field v*^a ``(M, G, d)`` whose G2P is the projected velocity P V^n (LR eq. 37).

    Args:
        order: XPIC order m >= 1.
        variant: one of ``XPIC_VARIANTS``.
        v: grid velocities after the first correction ``(M, G, d)`` in m/s.
        v_p2g: P2G velocities before any correction ``(M, G, d)`` (``"uncorrected"``).
        dv: first-correction velocity change ``(M, G, d)`` in m/s (``"paper"``).
        apply_A: u -> A_a u on fields ``(M, G, d)``.
        project: removes prescribed components of an increment (None: none).
    """
    if isinstance(order, bool) or not isinstance(order, int) or order < 1:
        raise ValueError(f"xpic order must be an integer >= 1, got {order!r}")
    if variant not in XPIC_VARIANTS:
        raise ValueError(f"xpic variant must be one of {XPIC_VARIANTS}, got {variant!r}")
    r = (v_p2g if variant == "uncorrected" else v).copy()
    with_dv = variant == "paper" and order >= 2
    s = -dv.copy() if with_dv else None
    acc = r + s if with_dv else r.copy()
    for k in range(1, order):
        r = r - apply_A(r)
        if project is not None:
            r = project(r)
        acc += r
        if with_dv and k <= order - 2:
            s = s - apply_A(s)
            if project is not None:
                s = project(s)
            acc += s
    return acc
