"""Argument checks of the LR contact functions (``bfemp.contact.lr``): arrays of the expected
shapes and kinds, or a ``ValueError`` naming what is wrong."""

from __future__ import annotations

import numpy as np

__all__ = [
    "check_F_R0",
    "check_clouds",
    "check_fit_options",
    "contact_rows",
    "dimension",
    "float_array",
    "grid_args",
    "int_array",
]


def float_array(name: str, a: object, shape: tuple) -> np.ndarray:
    """``a`` as a C-contiguous float64 array of ``shape`` (None = any), finite, or ValueError."""
    arr = np.asarray(a)
    if arr.dtype.kind not in "fiu":
        raise ValueError(f"{name} must be a real array, got dtype {arr.dtype}")
    arr = np.ascontiguousarray(arr, dtype=np.float64)
    if arr.ndim != len(shape) or any(
        s is not None and s != t for s, t in zip(shape, arr.shape, strict=True)
    ):
        want = "(" + ", ".join("*" if s is None else str(s) for s in shape) + ")"
        raise ValueError(f"{name} must have shape {want}, got {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(
            f"{name} has non-finite entries (first at {np.argwhere(~np.isfinite(arr))[0].tolist()})"
        )
    return arr


def int_array(name: str, a: object, ndim: int) -> np.ndarray:
    arr = np.asarray(a)
    if arr.dtype.kind not in "iu":
        raise ValueError(f"{name} must be an integer array, got dtype {arr.dtype}")
    if arr.ndim != ndim:
        raise ValueError(f"{name} must have {ndim} dimension(s), got shape {arr.shape}")
    return np.ascontiguousarray(arr, dtype=np.int64)


def dimension(name: str, a: np.ndarray) -> int:
    d = a.shape[-1]
    if d not in (2, 3):
        raise ValueError(f"{name}: d must be 2 or 3, got shape {a.shape}")
    return d


def check_F_R0(points_F: np.ndarray, points_R0: np.ndarray, what: str) -> None:
    det = np.linalg.det(points_F) if points_F.shape[0] else np.zeros(0)
    if np.any(det <= 0.0):
        bad = np.flatnonzero(det <= 0.0)
        raise ValueError(f"{what}: det F <= 0 at points {bad[:10].tolist()}")
    zero = points_R0 == 0.0
    if np.any(points_R0 < 0.0) or np.any(zero.any(axis=1) & ~zero.all(axis=1)):
        bad = np.flatnonzero((points_R0 < 0.0).any(axis=1) | (zero.any(axis=1) & ~zero.all(axis=1)))
        raise ValueError(
            f"{what}: R0 rows must be all positive (particles) or all zero (surface samples); "
            f"bad rows {bad[:10].tolist()}"
        )


def grid_args(
    nodes: object, n_nodes: int, material: object, n_materials: int, n_p: int
) -> tuple[np.ndarray, np.ndarray]:
    nodes = int_array("nodes", nodes, 2)
    if nodes.shape[0] != n_p:
        raise ValueError(f"nodes must have {n_p} rows (one per particle), got {nodes.shape}")
    if nodes.size and (nodes.min() < -1 or nodes.max() >= n_nodes):
        raise ValueError(
            f"nodes must be -1 or in [0, {n_nodes}), got range [{nodes.min()}, {nodes.max()}]"
        )
    material = int_array("material", material, 1)
    if material.shape != (n_p,):
        raise ValueError(f"material must have shape ({n_p},), got {material.shape}")
    if material.size and (material.min() < 0 or material.max() >= n_materials):
        raise ValueError(
            f"material must be in [0, {n_materials}), got range "
            f"[{material.min()}, {material.max()}]"
        )
    return nodes, material


def contact_rows(
    name: str, node: object, alpha: object, beta: object, n_nodes: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The contact rows' grid nodes ``node (C,)`` in [0, n_nodes) and materials ``alpha``,
    ``beta (C,)`` as int64 arrays of one shape (ValueError naming ``name`` otherwise); the
    materials' ranges are the caller's to check."""
    node = int_array("node", node, 1)
    alpha = int_array("alpha", alpha, 1)
    beta = int_array("beta", beta, 1)
    if alpha.shape != node.shape or beta.shape != node.shape:
        raise ValueError(
            f"{name}: node, alpha and beta must have one shape, got "
            f"{node.shape}, {alpha.shape}, {beta.shape}"
        )
    if node.size and (node.min() < 0 or node.max() >= n_nodes):
        raise ValueError(f"{name}: node must be in [0, {n_nodes})")
    return node, alpha, beta


def check_clouds(
    n_c: int, cloud_ptr: object, cloud_idx: object, cloud_side: object
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The CSR point clouds of ``n_c`` contact nodes as int arrays: row pointers ``(n_c + 1,)``,
    point indices ``(K,)`` and classes ``(K,)`` (-1 alpha, +1 beta)."""
    cloud_ptr = int_array("cloud_ptr", cloud_ptr, 1)
    cloud_idx = int_array("cloud_idx", cloud_idx, 1)
    cloud_side = int_array("cloud_side", cloud_side, 1)
    if cloud_ptr.shape != (n_c + 1,):
        raise ValueError(f"cloud_ptr must have shape ({n_c + 1},), got {cloud_ptr.shape}")
    if cloud_ptr[0] != 0 or np.any(np.diff(cloud_ptr) < 0) or cloud_ptr[-1] != cloud_idx.size:
        raise ValueError(
            "cloud_ptr must start at 0, never decrease and end at len(cloud_idx) "
            f"= {cloud_idx.size}, got ends {cloud_ptr[0]}, {cloud_ptr[-1]}"
        )
    if cloud_side.shape != cloud_idx.shape:
        raise ValueError(
            f"cloud_side must have the shape of cloud_idx {cloud_idx.shape}, got {cloud_side.shape}"
        )
    if np.any((cloud_side != -1) & (cloud_side != 1)):
        raise ValueError("cloud_side must hold -1 (alpha) or +1 (beta) only")
    return cloud_ptr, cloud_idx, cloud_side


def check_fit_options(
    dx: float, penalty: float, tol: float, linear_scale: float, thin: float, max_iterations: int
) -> None:
    """The scalar options of ``lr_planes`` (its Args), or a ``ValueError`` naming the bad one."""
    if not (np.isfinite(dx) and dx > 0.0):
        raise ValueError(f"dx must be a positive grid spacing in m, got {dx}")
    for name, val in (("penalty", penalty), ("tol", tol), ("linear_scale", linear_scale)):
        if not (np.isfinite(val) and val >= 0.0):
            raise ValueError(f"{name} must be finite and >= 0, got {val}")
    if linear_scale == 0.0:
        raise ValueError("linear_scale must be > 0")
    if not (np.isfinite(thin) and thin >= 0.0):
        raise ValueError(f"thin must be finite and >= 0 (cells), got {thin}")
    if int(max_iterations) != max_iterations or max_iterations < 0:
        raise ValueError(f"max_iterations must be an integer >= 0, got {max_iterations}")
