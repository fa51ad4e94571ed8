"""The finite-difference harness every energy term must pass (ARCHITECTURE.md, implicit step).

For a term (or any object with the energy contract) already started with ``begin_step``:

- gradient against central differences of the value, component by component;
- the unprojected Hessian against central differences of the gradient, column by column;
- the projected Hessian is symmetric positive semi-definite.

Use it for your own terms too::

    report = check_term(term, x, eps=1e-6)
    assert report.ok, report

and :func:`assert_reference` reruns a regression reference (:mod:`bfemp.regress`) in a test.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

__all__ = ["FDReport", "assert_reference", "check_term", "dense_hessian"]


def dense_hessian(term: object, x: np.ndarray, psd: bool) -> np.ndarray:
    """The term's Hessian at ``x (n,)`` as a dense ``(n, n)`` array (duplicates summed)."""
    term.solution_changed(x)
    t = term.hessian(x, psd)
    n = x.size
    return sp.coo_matrix((t.vals, (t.rows, t.cols)), shape=(n, n)).toarray()


@dataclass(frozen=True)
class FDReport:
    """Relative errors of one harness run (``ok`` when all are below the tolerances)."""

    gradient_error: float
    hessian_error: float
    asymmetry: float
    min_psd_eigenvalue: float
    tol: float

    @property
    def ok(self) -> bool:
        """All checks pass."""
        return (
            self.gradient_error < self.tol
            and self.hessian_error < self.tol
            and self.asymmetry < 1e-10
            and self.min_psd_eigenvalue >= -1e-9
        )


def _value(term: object, x: np.ndarray) -> float:
    term.solution_changed(x)
    return term.value(x)


def _gradient(term: object, x: np.ndarray) -> np.ndarray:
    term.solution_changed(x)
    return term.gradient(x)


def _relative(a: np.ndarray, b: np.ndarray, floor: float = 1e-300) -> float:
    scale = max(np.max(np.abs(a)), np.max(np.abs(b)), floor)
    return float(np.max(np.abs(a - b)) / scale)


def check_term(
    term: object,
    x: np.ndarray,
    *,
    eps: float = 1e-6,
    tol: float = 1e-5,
    hessian_floor: float = 1e-300,
) -> FDReport:
    """Run the harness at ``x (n,)`` with step ``eps`` (in the units of ``x``, m).

    Returns relative max-norm errors: gradient vs central differences of the value, unprojected
    Hessian vs central differences of the gradient; the asymmetry and smallest eigenvalue
    (relative to the largest magnitude) of the projected Hessian. ``hessian_floor`` (units of
    the Hessian) is the smallest scale the Hessian error is relative to, for terms whose
    Hessian vanishes (e.g. sliding friction in 2D) and whose finite differences are pure noise.
    """
    x = np.asarray(x, dtype=np.float64)
    n = x.size
    grad = _gradient(term, x)
    fd_grad = np.empty(n)
    fd_hess = np.empty((n, n))
    for k in range(n):  # test-only: the harness differentiates one DOF at a time
        e = np.zeros(n)
        e[k] = eps
        fd_grad[k] = (_value(term, x + e) - _value(term, x - e)) / (2 * eps)
        fd_hess[:, k] = (_gradient(term, x + e) - _gradient(term, x - e)) / (2 * eps)
    hess = dense_hessian(term, x, psd=False)
    projected = dense_hessian(term, x, psd=True)
    scale = max(np.max(np.abs(projected)), 1e-300)
    asym = float(np.max(np.abs(projected - projected.T)) / scale)
    min_eig = float(np.linalg.eigvalsh(0.5 * (projected + projected.T)).min() / scale)
    term.solution_changed(x)
    return FDReport(
        gradient_error=_relative(grad, fd_grad),
        hessian_error=_relative(hess, fd_hess, hessian_floor),
        asymmetry=asym,
        min_psd_eigenvalue=min_eig,
        tol=tol,
    )


def assert_reference(path: str | os.PathLike, *, update: bool = False) -> object:
    """Rerun the regression reference ``path`` (a scene file with ``[regress]``, see
    :mod:`bfemp.regress`) and raise ``AssertionError`` with the drift table when a quantity
    drifted; with ``update=True`` rewrite its stored trajectory instead.

    Returns the :class:`bfemp.regress.Report` (or, with ``update``, the changes written).
    """
    from bfemp import regress

    ref = regress.load_reference(path)
    if update:
        return regress.update(ref)
    report = regress.check(ref)
    if not report.ok:
        raise AssertionError(
            f"regression reference drifted:\n{report.table()}\n(rewrite it on purpose with: "
            f"bfemp regress {ref.name} --update --dir {ref.scene_file.parent})"
        )
    return report
