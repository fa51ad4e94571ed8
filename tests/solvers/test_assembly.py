"""Triplet assembly: equals scipy's COO -> CSC, pattern caching, fixed-DOF elimination."""

import numpy as np
import pytest
import scipy.sparse as sp

from solvers.assembly import TripletAssembler, Triplets


def _random_triplets(rng, n, nnz):
    rows = rng.integers(0, n, nnz)
    cols = rng.integers(0, n, nnz)
    # Symmetrise so the result is a full symmetric matrix like the ones Newton assembles.
    return Triplets(
        np.concatenate([rows, cols]),
        np.concatenate([cols, rows]),
        np.tile(rng.standard_normal(nnz), 2),
    )


def _reference(t, n):
    return sp.coo_matrix((t.vals, (t.rows, t.cols)), shape=(n, n)).tocsc()


def test_assembly_matches_scipy_coo_with_duplicates():
    rng = np.random.default_rng(0)
    n = 40
    t = _random_triplets(rng, n, 600)  # many duplicates at this density
    assert len(set(zip(t.rows.tolist(), t.cols.tolist(), strict=True))) < t.nnz
    A = TripletAssembler(n).assemble(t)
    ref = _reference(t, n)
    assert isinstance(A, sp.csc_matrix)
    assert A.shape == (n, n)
    assert A.has_sorted_indices
    np.testing.assert_allclose(A.toarray(), ref.toarray(), rtol=0, atol=1e-13)
    # Canonical: one stored entry per distinct (row, col) of the triplets.
    assert A.nnz == len(set(zip(t.rows.tolist(), t.cols.tolist(), strict=True)))


def test_cached_pattern_gives_identical_results_with_new_values():
    rng = np.random.default_rng(1)
    n = 30
    t = _random_triplets(rng, n, 300)
    asm = TripletAssembler(n)
    asm.assemble(t)
    assert asm.pattern_changed and asm.n_rebuilds == 1
    version = asm.pattern_version
    new_vals = rng.standard_normal(t.nnz)
    # New arrays with equal contents: the cache must be hit.
    t2 = Triplets(t.rows.copy(), t.cols.copy(), new_vals)
    A2 = asm.assemble(t2)
    assert not asm.pattern_changed
    assert asm.pattern_version == version and asm.n_rebuilds == 1
    fresh = TripletAssembler(n).assemble(t2)
    assert np.array_equal(A2.indptr, fresh.indptr)
    assert np.array_equal(A2.indices, fresh.indices)
    np.testing.assert_allclose(A2.data, fresh.data, rtol=1e-15, atol=1e-15)
    np.testing.assert_allclose(A2.toarray(), _reference(t2, n).toarray(), atol=1e-13)


def test_pattern_change_is_detected_and_versions_are_unique():
    rng = np.random.default_rng(2)
    n = 20
    t = _random_triplets(rng, n, 100)
    asm, other = TripletAssembler(n), TripletAssembler(n)
    asm.assemble(t)
    other.assemble(t)
    v1 = asm.pattern_version
    assert other.pattern_version != v1  # never shared between assemblers
    # Same length, one index moved: must rebuild.
    rows = t.rows.copy()
    rows[5] = (rows[5] + 1) % n
    t_moved = Triplets(rows, t.cols, t.vals)
    A = asm.assemble(t_moved)
    assert asm.pattern_changed and asm.pattern_version != v1 and asm.n_rebuilds == 2
    np.testing.assert_allclose(A.toarray(), _reference(t_moved, n).toarray(), atol=1e-13)
    # In-place mutation of the caller's array is detected too (the assembler keeps copies).
    rows[7] = (rows[7] + 3) % n
    A = asm.assemble(t_moved)
    assert asm.pattern_changed
    np.testing.assert_allclose(A.toarray(), _reference(t_moved, n).toarray(), atol=1e-13)
    # Different length: rebuild.
    asm.assemble(Triplets.concatenate([t, Triplets([0], [0], [1.0])]))
    assert asm.pattern_changed


def test_free_mask_gives_principal_submatrix():
    rng = np.random.default_rng(3)
    n = 25
    t = _random_triplets(rng, n, 200)
    free = rng.random(n) > 0.3
    asm = TripletAssembler(n, free=free)
    A = asm.assemble(t)
    ref = _reference(t, n).toarray()[np.ix_(free, free)]
    assert A.shape == (free.sum(), free.sum())
    np.testing.assert_allclose(A.toarray(), ref, atol=1e-13)
    t2 = Triplets(t.rows, t.cols, 2.0 * t.vals)
    A2 = asm.assemble(t2)
    assert not asm.pattern_changed
    np.testing.assert_allclose(A2.toarray(), 2.0 * ref, atol=1e-13)


def test_from_blocks_and_helpers():
    dofs = np.array([[0, 2], [2, 3]])
    blocks = np.array([[[1.0, 2.0], [2.0, 5.0]], [[3.0, -1.0], [-1.0, 4.0]]])
    t = Triplets.from_blocks(dofs, blocks)
    dense = TripletAssembler(4).assemble(t).toarray()
    expected = np.zeros((4, 4))
    for s in range(2):
        expected[np.ix_(dofs[s], dofs[s])] += blocks[s]
    np.testing.assert_array_equal(dense, expected)
    np.testing.assert_array_equal(TripletAssembler(4).assemble(t.scaled(3.0)).toarray(), 3 * dense)
    assert Triplets.concatenate([]).nnz == 0
    assert TripletAssembler(4).assemble(Triplets.empty()).nnz == 0


def test_bad_input_raises_value_error():
    with pytest.raises(ValueError, match="equal lengths"):
        Triplets([0, 1], [0], [1.0, 2.0])
    with pytest.raises(ValueError, match="out of range"):
        TripletAssembler(3).assemble(Triplets([0, 3], [0, 0], [1.0, 1.0]))
    with pytest.raises(ValueError, match="free"):
        TripletAssembler(3, free=np.ones(4, bool))
    with pytest.raises(ValueError, match="blocks"):
        Triplets.from_blocks(np.zeros((2, 3), int), np.zeros((2, 2, 2)))


def test_sums_have_the_bits_of_bincount_with_duplicates_and_dropped_dofs():
    rng = np.random.default_rng(7)
    n = 300
    t = _random_triplets(rng, n, 20_000)  # ~45 entries per slot, in scattered order
    free = rng.random(n) > 0.2
    asm = TripletAssembler(n, free=free)
    A = asm.assemble(t)
    # np.bincount adds in triplet order from 0.0; the parallel slot sums must give those bits
    ref = np.bincount(asm._slots, weights=t.vals, minlength=A.nnz + 1)[: A.nnz]
    assert np.array_equal(A.data, ref)
    vals = rng.standard_normal(t.nnz) * 10.0 ** rng.integers(-8, 8, t.nnz)  # wide magnitudes
    B = asm.assemble(Triplets(t.rows, t.cols, vals))
    assert np.array_equal(B.data, np.bincount(asm._slots, weights=vals, minlength=A.nnz + 1)[:-1])


def test_stacked_patterns_carry_a_key_and_the_assembler_trusts_it():
    from solvers.assembly import TripletStacker

    rng = np.random.default_rng(8)
    n = 30
    a, b = _random_triplets(rng, n, 50), _random_triplets(rng, n, 40)
    stacker = TripletStacker()
    first = stacker.stack([a, b])
    again = stacker.stack([a, Triplets(b.rows, b.cols, 2.0 * b.vals)])  # same index objects
    assert first.pattern_key is not None and again.pattern_key == first.pattern_key
    assert again.rows is first.rows
    c = Triplets(b.rows.copy(), b.cols, b.vals)  # equal arrays, other objects: a new pattern
    other = stacker.stack([a, c])
    assert other.pattern_key != first.pattern_key
    asm = TripletAssembler(n)
    asm.assemble(first)
    A = asm.assemble(again)
    assert not asm.pattern_changed and asm.n_rebuilds == 1
    np.testing.assert_allclose(A.toarray(), _reference(again, n).toarray(), atol=1e-13)
    # unkeyed or differently keyed triplets are compared: equal arrays keep the pattern,
    # a moved index rebuilds it
    asm.assemble(Triplets(again.rows.copy(), again.cols.copy(), again.vals))
    assert not asm.pattern_changed
    asm.assemble(other)
    assert not asm.pattern_changed  # a new key, but the same arrays (c equals b)
    rows = first.rows.copy()
    rows[3] = (rows[3] + 1) % n
    moved = Triplets(rows, first.cols, first.vals, pattern_key=None)
    B = asm.assemble(moved)
    assert asm.pattern_changed and asm.n_rebuilds == 2
    np.testing.assert_allclose(B.toarray(), _reference(moved, n).toarray(), atol=1e-13)


def _sorted_route(r, c, m):
    """The pattern as ``TripletAssembler`` built it before the counting sorts: ``np.unique`` of
    the column-major keys and a stable argsort of the slots (dropped triplets: -1, slot nnz)."""
    keep = (r >= 0) & (c >= 0)
    unique, inverse = np.unique(c[keep] * m + r[keep], return_inverse=True)
    nnz = unique.size
    indptr = np.zeros(m + 1, dtype=np.int64)
    np.cumsum(np.bincount(unique // m, minlength=m), out=indptr[1:])
    slots = np.full(r.size, nnz, dtype=np.int64)
    slots[keep] = inverse.ravel()
    starts = np.zeros(nnz + 1, dtype=np.int64)
    np.cumsum(np.bincount(slots, minlength=nnz + 1)[:nnz], out=starts[1:])
    return indptr, unique % m, slots, np.argsort(slots, kind="stable"), starts


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_counting_sort_pattern_equals_the_unique_and_argsort_route(seed):
    """The numba pattern (``solvers._pattern_kernels``) gives the arrays of the sorted route
    exactly: CSC structure, each triplet's slot, and the triplets' order inside each slot (the
    order of the sums, so the bits of the assembled values); with duplicates, dropped triplets,
    empty columns and a column holding one row many times."""
    from solvers._pattern_kernels import _csc_pattern

    rng = np.random.default_rng(seed)
    m = 97
    r = rng.integers(-1, m, 5000)  # -1: dropped (a fixed DOF)
    c = rng.integers(-1, m, 5000)
    c[c == 13] = 14  # column 13 empty
    r[:300], c[:300] = 5, 40  # one entry repeated
    got = _csc_pattern(r, c, m)
    want = _sorted_route(r, c, m)
    for name, g, w in zip(
        ("indptr", "indices", "slots", "order", "starts"), got, want, strict=True
    ):
        assert np.array_equal(g, w), name
    assert got[0][14] == got[0][13]  # the empty column


def test_a_moved_pattern_is_rebuilt_to_a_fresh_assemblers_matrix():
    """After triplets move to other slots (particles crossing cells), a reused assembler's
    matrix has the structure and the bits of a fresh assembler's."""
    rng = np.random.default_rng(3)
    n = 200
    free = rng.random(n) > 0.1
    asm = TripletAssembler(n, free=free)
    t = _random_triplets(rng, n, 4000)
    asm.assemble(t)
    moved = Triplets((t.rows + rng.integers(0, 3, t.nnz)) % n, t.cols, t.vals)
    A, B = asm.assemble(moved), TripletAssembler(n, free=free).assemble(moved)
    assert asm.pattern_changed
    for name in ("indptr", "indices", "data"):
        assert np.array_equal(getattr(A, name), getattr(B, name)), name
    ref = _reference(moved, n)[free][:, free]
    np.testing.assert_allclose(A.toarray(), ref.toarray(), rtol=1e-13, atol=1e-13)
