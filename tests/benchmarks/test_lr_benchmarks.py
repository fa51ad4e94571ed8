"""The LR reproductions in quick mode: lr_compression (Fig. 5), lr_contact_time (Fig. 2B),
lr_ellipses (Fig. 6), the BFEMP scenes under lr (smoke) and lr's update variants (smoke)."""

import numpy as np

from benchmarks import lr_compression, lr_contact_time, lr_ellipses, lr_scenes, lr_variants


def test_lr_compression_quick_stress_error_against_single_material(tmp_path):
    rec = lr_compression.run("quick", tmp_path)["compression"]
    err = rec["max_abs_error_percent"]
    assert err["lr_flip"] < lr_compression.TOL_LR  # (T) LR < 1 %
    # the grid detectors are far off, as in the paper's Fig. 5
    assert err["velocity"] > 3.0 * err["lr_flip"] and err["cp_0.8"] > 10.0 * err["lr_flip"]
    # the reference runs are the same particles as one body: their stress is real compression
    assert min(rec["runs"]["smm_flip"]["stress"]) < -1e8
    assert rec["runs"]["lr_flip"]["mean_contact_nodes"] > 10
    assert (tmp_path / "lr_compression_quick.json").exists()
    assert (tmp_path / "lr_compression_quick.png").exists()


def test_lr_contact_time_quick_exact_for_lr_early_for_the_velocity_detector(tmp_path):
    rec = lr_contact_time.run("quick", tmp_path)
    assert rec["targets"]["lr_within_2pct"]
    assert rec["targets"]["velocity_detector_early"]
    for where in ("grid_line", "mid_cell"):
        assert abs(rec["cases"][f"{where}/lr"]["relative_error"]) < 0.02


def test_lr_ellipses_smoke_interpenetration(tmp_path):
    """The quick box to 35 % (the quick record, to 50 %, has LR 0 against CP 400)."""
    rec = lr_ellipses.run("smoke", tmp_path)
    lr, cp = rec["runs"]["lr"], rec["runs"]["cp_0.8"]
    assert rec["targets"]["lr_interpenetration_below_0.1pct"]
    assert rec["targets"]["lr_below_cp"]
    assert cp["interpenetrating_end"] > 10 * max(lr["interpenetrating_end"], 1)
    assert lr["final_stress_Pa"] > 1e9  # the piston really compresses the packing
    assert np.isfinite(rec["stress_ratio_lr_over_cp"])


def test_lr_scenes_smoke_rings_keep_momentum(tmp_path):
    rec = lr_scenes.run("smoke", tmp_path)
    runs = rec["rings"]["runs"]
    for name, r in runs.items():
        assert r["error"] is None, (name, r["error"])
    assert rec["lr_mpm_rings_drift_below_1e-10"]
    assert runs["lr_fem_material"]["momentum_drift_rel"] < 1e-10
    assert runs["lr_fem_material"]["contact_steps"] > 0


def test_lr_variants_smoke_every_update_holds_the_fixed_slope_and_c1_the_column(tmp_path):
    """The slope box lands on the fixed FEM slope and slides at mu = 0.1 (eq. 40). The fixed
    slope is rigid in lr's contact law (issue 40), so every update gives the analytic rate
    (measured error 0.021 each; before, f^{C,1} kept the landing velocity, -0.061 m/s into the
    slope, and slid at nearly the frictionless rate, 0.90) and none is flagged. On the
    compressed column f^{C,1} and one correction (lr's default) hold the paper's 1 %, and
    f^{C,0} is the worse one (1.5 % against 0.33 / 0.36 %). The landing f^{C,1} still loses
    (a deformable plate) is ``tests/bfemp/test_lr_drop.py``'s."""
    rec = lr_variants.run("smoke", tmp_path)
    slope, column = rec["slope"]["runs"], rec["compression"]["runs"]
    for name in ("flip_c1", "flip_c0", "once"):
        run = slope[name]
        assert abs(run["bottom_row_normal_velocity_m_s"]) < 0.01, name
        assert run["error"] < 0.03, name
        assert run["settle"]["first_correction_windows"] == 0
        assert run["slide"]["first_correction_windows"] == 0
    for name in ("flip_c1", "once"):
        assert column[name]["error_pct"] < lr_compression.TOL_LR, name
    assert column["flip_c1"]["run"]["first_correction_windows"] == 0
    assert column["flip_c1"]["run"]["first_over_second"] < 0.1
    assert column["flip_c0"]["error_pct"] > 3.0 * column["flip_c1"]["error_pct"]
    assert (tmp_path / "lr_variants_smoke.json").exists()
    assert (tmp_path / "lr_variants_smoke.png").exists()
