"""Per-Newton-iteration cost of MPM bodies in the implicit potential (issue: MPM bodies).

Cases (full mode): a 2D block of ~100k particles (4 per cell) and a 3D block of ~100k particles
(8 per cell), Neo-Hookean, resting on a slip floor under gravity, one backward-Euler step.
Quick mode: ~10k particles each.

Recorded per case: P2G (stencils + transfer) and G2P times, elasticity value / gradient /
projected-Hessian accumulation into the grid's node-pair pattern, triplet-to-CSC, CHOLMOD symbolic
and numeric factorisation, the step's own phase split. Targets: assembly faster than the
factorisation of the same system; P2G + G2P < 10 % of a Newton iteration.
"""

from __future__ import annotations

from benchmarks import catalogue
from benchmarks._phases import median_time, newton_benchmark, newton_phases, warm_stepper
from bfemp.mpm.step import prepare_mpm_step
from bfemp.mpm.transfer import grid_to_particles

CASES = {
    "full": {"2d": dict(cells=(160, 160), ppc=4), "3d": dict(cells=(30, 30, 14), ppc=8)},
    "quick": {"2d": dict(cells=(50, 50), ppc=4), "3d": dict(cells=(14, 14, 7), ppc=8)},
}


def _measure(name: str, matrices: dict, dim: int, cells: tuple[int, ...], ppc: int) -> dict:
    model = catalogue.mpm_block_scene(dim, cells, ppc).build()
    stepper, state = warm_stepper(model, dt=0.01, tol=1e-4)
    out = {"dim": dim, "particles": int(model.n_particles)}
    out["p2g_s"] = median_time(lambda: prepare_mpm_step(model, state, "apic", False))
    mpm = prepare_mpm_step(model, state, "apic", False)
    st = mpm.stencils
    out["grid_nodes"] = int(st.n_nodes)
    moved = st.active_x + 1e-3
    out["g2p_s"] = median_time(
        lambda: grid_to_particles(
            "apic",
            st.nodes,
            st.weights,
            st.grads,
            st.active_x,
            moved,
            mpm.fields.velocity,
            mpm.fields.velocity,
            None,
            state.mpm_x,
            state.mpm_v,
            state.mpm_F,
        )
    )
    out.update(newton_phases(stepper, state, matrices=matrices, name=name, step_repeats=3))
    out["transfer_fraction_of_iteration"] = (out["p2g_s"] + out["g2p_s"]) / out[
        "time_per_newton_iteration_s"
    ]
    return out


PHASES = ("p2g", "g2p", "assembly", "factorize")
TITLE = "MPM: transfers, assembly and CHOLMOD per Newton iteration"
BENCHMARK = newton_benchmark("perf_mpm", __doc__, CASES, _measure, PHASES, "particles", TITLE)
run = BENCHMARK.run
