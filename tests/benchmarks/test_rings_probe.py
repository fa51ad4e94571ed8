"""The rings timing probe's reduction: warm-up steps left out, the extrapolation's arithmetic."""

from types import SimpleNamespace

import numpy as np
import pytest

from benchmarks import _rings_probe as probe
from benchmarks import rings


def _table(n_free, n_touch, free_s, touch_s, warm_s):
    """A metrics table: ``n_free`` free steps then ``n_touch`` contact steps (the first two of
    them ``warm_s`` long: contact kernels compiling), the first step 10 s (compiling)."""
    step = np.r_[np.full(n_free, free_s), np.full(n_touch, touch_s)]
    step[0] = 10.0
    step[n_free : n_free + probe.WARM_CONTACT_STEPS] = warm_s
    pairs = np.r_[np.zeros(n_free), np.full(n_touch, 7.0)]
    return {
        "time_step": step,
        "time_factorize": 0.5 * step,
        "contact_pairs": pairs,
        "iterations_newton": np.r_[np.ones(n_free), np.full(n_touch, 3.0)],
    }


def _sim():
    zeros = np.zeros((4, 2))
    state = SimpleNamespace(
        t=0.1, mpm_x=zeros, mpm_v=zeros, mpm_F=np.zeros((4, 2, 2)), fem_x=zeros, fem_v=zeros
    )
    return SimpleNamespace(state=state)


def test_means_leave_out_the_compiling_steps_and_the_extrapolation_adds_them_up():
    table = _table(20, 10, 0.3, 1.2, 50.0)
    wall = float(table["time_step"].sum()) + 30 * 0.1  # 0.1 s a step outside the stepper
    run = probe.summarise(table, _sim(), wall, cpu_s=1.0)
    assert run["mean_step_free_s"] == pytest.approx(0.3)
    assert run["mean_step_contact_s"] == pytest.approx(1.2)
    assert run["first_contact_steps_s"] == [50.0, 50.0]
    assert run["phase_s_per_contact_step"]["factorize"] == pytest.approx(0.6)
    assert run["s_per_contact_iteration"] == pytest.approx(0.4)
    full = {"apic": {"steps": 100, "contact_steps": 60, "newton_iterations": 250}}
    ext = probe.extrapolate({"apic": run}, full)
    assert ext["by_steps_s"]["apic"] == pytest.approx(40 * 0.3 + 60 * 1.2 + 100 * 0.1)
    # 250 iterations less 40 free steps at one each: 210 at 0.4 s
    assert ext["by_iterations_s"]["apic"] == pytest.approx(40 * 0.3 + 210 * 0.4 + 100 * 0.1)


def test_the_probe_writes_its_own_record_and_keeps_the_full_scene():
    assert rings.record("full_probe", {}) == "rings_full_probe"
    assert rings.record("full", {}) == rings.record("quick", {}) == "rings"
    full, cut = rings.MODES["full"], rings.MODES["full_probe"]
    assert {k: v for k, v in cut.items() if k != "t_end"} == {
        k: v for k, v in full.items() if k != "t_end"
    }
    assert cut["t_end"] > 0.025  # past the first contact (2 m gap closed at 80 m/s)
