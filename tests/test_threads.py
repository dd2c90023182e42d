"""The compiled Newton iteration on several threads (rvfmu/core/statics/newton.py): the same results
to the bit as on one, on the no-load route with the bearing clearances and under load."""

import numpy as np
import pytest
from conftest import ROOT

from rvfmu.core.statics import newton_kernel
from rvfmu.core.statics.newton import MIN_PAIRS_PER_THREAD, kernel_threads
from rvfmu.core.statics.quasistatic import te_curve, windup

pytestmark = pytest.mark.skipif(not newton_kernel.COMPILED, reason="the threads split the compiled kernel")


@pytest.fixture(scope="module")
def clearances():
    """Four reducers of the complete RV-40E-121 study: every tolerance, bearing clearances too."""
    from tolerance import montecarlo
    from tolerance.sampling import errors_from_unit
    from tolerance.study import load_study

    study = load_study(ROOT / "studies" / "rv40e_121_full.toml")
    return study.design, errors_from_unit(study, montecarlo.rows(study, 0, 4))


@pytest.mark.parametrize("load", [0.0, 412.0], ids=["no load", "rated"])
def test_threads_give_the_one_thread_results_to_the_bit(clearances, monkeypatch, load):
    design, errors = clearances
    assert float(errors.arrays()["crank_disc_clearance"].max()) > 0.0
    runs = []
    for threads in ("1", "2", "3"):
        monkeypatch.setenv("RVTE_THREADS", threads)
        curve = te_curve(design, errors, -load, 640)  # 4 x 640 pairs: split over the threads
        assert 4 * 640 >= int(threads) * MIN_PAIRS_PER_THREAD
        runs.append((curve.te, curve.converged, windup(design, errors).windup))
    for other in runs[1:]:
        for a, b in zip(runs[0], other):
            assert np.array_equal(a, b)


@pytest.mark.parametrize("load", [0.0, 412.0], ids=["no load", "rated"])
def test_chunks_on_threads_give_the_one_thread_results_to_the_bit(clearances, monkeypatch, load):
    """Several chunks of pairs: each runs on a thread of its own (solver.map_chunks), its
    compiled iteration on that thread alone."""
    from rvfmu.core.statics import newton, solver

    design, errors = clearances
    monkeypatch.setattr(solver, "CHUNK", 160)  # 4 x 640 pairs: 16 chunks, >= 3 a thread
    seen = []
    original = newton.kernel_threads
    monkeypatch.setattr(newton, "kernel_threads", lambda: seen.append(original()) or seen[-1])
    runs = []
    for threads in ("1", "2", "3"):
        monkeypatch.setenv("RVTE_THREADS", threads)
        seen.clear()
        curve = te_curve(design, errors, -load, 640)
        runs.append((curve.te, curve.converged))
        if threads != "1":  # the chunks asked for the threads, each chunk's kernel for one
            assert int(threads) in seen and 1 in seen
    for other in runs[1:]:
        for a, b in zip(runs[0], other):
            assert np.array_equal(a, b)


def test_the_thread_count(monkeypatch):
    monkeypatch.setenv("RVTE_THREADS", "3")
    assert kernel_threads() == 3
    monkeypatch.delenv("RVTE_THREADS")
    assert kernel_threads() >= 1
    for bad in ("0", "two", "-1"):
        monkeypatch.setenv("RVTE_THREADS", bad)
        with pytest.raises(ValueError, match="RVTE_THREADS"):
            kernel_threads()
