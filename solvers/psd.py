"""Projection of small symmetric matrices onto the positive semi-definite cone.

Projected Newton (BFEMP Sec. 5, following Teran et al.) replaces every local stencil Hessian
``H = V diag(w) V^T`` by its closest PSD matrix in the Frobenius norm, ``V diag(max(w, 0)) V^T``,
before summation; the sum is then PSD and, with the mass matrix, positive definite.  Each block
of a stack is decomposed by a numba kernel (Householder tridiagonalisation and implicit QL, see
:mod:`solvers._psd_kernels`; faster than a batched ``np.linalg.eigh`` on blocks of a few rows,
whose per-matrix overhead dominates there); blocks that are already PSD are returned bit-for-bit
unchanged.
"""

from __future__ import annotations

import numpy as np

from solvers._psd_kernels import _project_stack

__all__ = ["is_symmetric_psd", "project_psd"]


def _check_blocks(blocks: np.ndarray) -> np.ndarray:
    blocks = np.asarray(blocks, dtype=np.float64)
    if blocks.ndim != 3 or blocks.shape[1] != blocks.shape[2]:
        raise ValueError(f"blocks must be a stack of square matrices (S, n, n), got {blocks.shape}")
    return blocks


def project_psd(blocks: np.ndarray, eps: float = 0.0) -> np.ndarray:
    """Clamp the eigenvalues of each symmetric block from below at ``eps``.

    Args:
        blocks: stack of symmetric matrices (S, n, n), any units; the symmetric part
            ``(B + B^T) / 2`` is what gets projected.
        eps: lower bound for the eigenvalues (>= 0), in the units of ``blocks``.

    Returns:
        New array (S, n, n): ``V diag(max(w, eps)) V^T`` for blocks with an eigenvalue below
        ``eps`` (eigenvectors preserved, exactly symmetric), the input block unchanged otherwise;
        NaN for a block with a non-finite entry.
    """
    blocks = _check_blocks(blocks)
    if not np.isfinite(eps) or eps < 0.0:
        raise ValueError(f"project_psd eps must be finite and >= 0, got {eps!r}")
    out = np.array(blocks, dtype=np.float64, order="C", copy=True)
    if out.shape[0] == 0 or out.shape[1] == 0:
        return out
    _project_stack(out, float(eps))
    return out


def is_symmetric_psd(blocks: np.ndarray, rtol: float = 1e-10) -> bool:
    """Whether every block is symmetric and PSD up to a relative tolerance.

    Args:
        blocks: stack of matrices (S, n, n).
        rtol: per block, ``|B - B^T| <= rtol * max|B|`` and
            ``min eig >= -rtol * max|eig|`` are required.

    Returns:
        True iff all blocks pass both tests.
    """
    blocks = _check_blocks(blocks)
    if blocks.shape[0] == 0 or blocks.shape[1] == 0:
        return True
    if not np.all(np.isfinite(blocks)):
        return False
    scale = np.abs(blocks).max(axis=(1, 2))
    asym = np.abs(blocks - blocks.transpose(0, 2, 1)).max(axis=(1, 2))
    if np.any(asym > rtol * scale):
        return False
    eigval = np.linalg.eigvalsh(0.5 * (blocks + blocks.transpose(0, 2, 1)))
    return bool(np.all(eigval[:, 0] >= -rtol * np.abs(eigval).max(axis=1)))
