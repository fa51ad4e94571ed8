"""benchmarks.ccd_oracle: the record's shape, zero bfemp false negatives on a few cases per family,
and ipctk columns that are None without ipctk (its optional extra)."""

import json

import numpy as np
import pytest

from benchmarks import ccd_oracle


def test_run_writes_a_record_without_false_negatives(tmp_path, monkeypatch):
    monkeypatch.setitem(ccd_oracle.CASES, "quick", 4)
    monkeypatch.setattr(ccd_oracle, "ipctk", None)
    out = ccd_oracle.run("quick", tmp_path)
    record = json.loads((tmp_path / "ccd_oracle_quick.json").read_text())
    assert out["json"].endswith("ccd_oracle_quick.json")  # as the committed quick record
    assert len(record["families"]) == len(ccd_oracle.FAMILIES) * len(ccd_oracle.KINDS) + 2
    assert {"turning/point_edge", "tangent/point_edge"} <= set(record["families"])
    assert record["bfemp_false_negatives"] == 0
    assert record["ipctk"] is None and record["ipctk_false_negatives"] is None
    sliding = record["families"]["sliding/edge_edge"]
    assert sliding["iterations_max"] == 1 and sliding["bfemp_no_contact_toi_1_fraction"] == 1.0


def test_false_negative_rule():
    from fractions import Fraction

    assert not ccd_oracle.false_negative(0.4, Fraction(1, 2))
    assert ccd_oracle.false_negative(0.5, Fraction(1, 2))  # at the contact is too late
    assert ccd_oracle.false_negative(1e-30, Fraction(0))  # touching at 0 needs exactly 0
    assert not ccd_oracle.false_negative(0.0, Fraction(0))
    assert not ccd_oracle.false_negative(1.0, None)


@pytest.mark.parametrize("kind", ccd_oracle.KINDS)
def test_families_are_reproducible_and_translate_rigidly(kind):
    X, dX = ccd_oracle.family("far", kind, 5, seed=3)
    X2, dX2 = ccd_oracle.family("far", kind, 5, seed=3)
    assert np.array_equal(X, X2) and np.array_equal(dX, dX2)
    n_a = ccd_oracle.N_SIDE_A[kind]
    assert np.all(dX[:, :n_a] == dX[:, :1]) and np.all(dX[:, n_a:] == dX[:, n_a : n_a + 1])


def test_surd_sign_and_order():
    from fractions import Fraction

    S = ccd_oracle.Surd
    root2 = S(0, 1, 2)
    assert (root2 - Fraction(141, 100)).sign() == 1 and (root2 - Fraction(142, 100)).sign() == -1
    assert (root2 * root2 - 2).sign() == 0
    assert ccd_oracle._less(S(0, 1, 2), S(0, 1, 3))  # sqrt 2 < sqrt 3, different radicands
    assert ccd_oracle._less(S(1, 1, 3), S(2, 1, 2))  # 2.732 < 3.414
    assert not ccd_oracle._less(S(2, 1, 2), S(1, 1, 3))
    assert not ccd_oracle._less(S(0, 1, 2), S(0, 1, 2))


class _FakeTightInclusion:
    """Stands in for ipctk's ``TightInclusionCCD``: a hit at t = x0[0] of the point, no
    collision for x0[0] = 1, and a query that never returns for x0[0] = 2 (as ipctk 1.6.1's
    point-edge CCD on the defect case of issue 44)."""

    conservative_rescaling = 0.8

    def point_edge_ccd(self, p0, e00, e01, p1, e10, e11):
        assert self.conservative_rescaling == 1.0
        if p0[0] == 2.0:
            while True:
                pass
        return p0[0] != 1.0, p0[0]


def test_ipctk_queries_answer_and_a_stuck_one_is_killed_and_counted(monkeypatch):
    import sys
    import types

    fake = types.SimpleNamespace(TightInclusionCCD=_FakeTightInclusion)
    monkeypatch.setitem(sys.modules, "ipctk", fake)
    monkeypatch.setattr(ccd_oracle, "ipctk", fake)
    X = np.zeros((4, 3, 2))
    X[:, 0, 0] = [0.25, 2.0, 1.0, 0.5]  # the second query hangs; the ones after it still run
    toi = ccd_oracle.ipctk_toi("point_edge", X, np.zeros_like(X), timeout=0.5)
    assert toi[0] == 0.25 and np.isnan(toi[1]) and toi[2] == 1.0 and toi[3] == 0.5
