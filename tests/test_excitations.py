"""The TE amplitude at each excitation of a dynamic run (rvfmu/core/dynamics/simulation.py,
docs/model.md section 7): against synthetic signals whose sines are known."""

import dataclasses
import json
import math

import numpy as np
import pytest

from rvfmu import cli
from rvfmu.core.base.units import ARCSEC
from rvfmu.core.dynamics.simulation import Excitations, amplitude_at, simulate


@pytest.mark.parametrize("offset", [0.0, 0.25, 0.5, 0.37])
def test_a_sine_off_the_bins_reads_its_amplitude(offset):
    """Sines at a bin frequency and off it by a quarter, a half and 0.37 of a bin, beside a
    larger one 5 bins away and a drift: each amplitude within 0.5 % (the plain spectrum's
    highest bin reads a Hann sine half a bin off 15 % low)."""
    step, count = 1e-4, 6000
    t = np.arange(count) * step
    resolution = 1.0 / (count * step)
    f1 = 40.0 * resolution + offset * resolution
    f2 = f1 + 5.0 * resolution
    signal = 0.3 * np.sin(2 * np.pi * f1 * t + 0.7) + 2.0 * np.cos(2 * np.pi * f2 * t) + 0.5 * t
    assert amplitude_at(signal, step, f1) == pytest.approx(0.3, rel=5e-3)
    assert amplitude_at(signal, step, f2) == pytest.approx(2.0, rel=5e-3)
    if offset == 0.5:
        bins = (
            2.0 * np.abs(np.fft.rfft((signal - signal.mean()) * np.hanning(count))) / np.hanning(count).sum()
        )
        assert bins[40:42].max() < 0.9 * 0.3 + 0.02  # what reading the bin would give


@pytest.fixture(scope="module")
def run(rv40):
    return simulate(rv40, None, 1600.0, load=206.0, duration=0.6)


def test_a_run_reports_every_excitation_and_its_second_harmonic(run, rv40):
    """A run's TE replaced by known sines at the excitations' frequencies (none on a bin):
    each read within 2 % (0.6 s at speed: the closest two, the crank's 2nd order and the
    input's, 9 Hz apart, are 5.4 bins apart), and the orders above Nyquist say so."""
    ex = Excitations.at(rv40, 1600.0)
    expected = dict(ex.with_harmonics())
    assert list(expected) == [
        "input rotation",
        "input rotation x2",
        "crank rotation",
        "crank rotation x2",
        "pin passing",
        "pin passing x2",
        "stage-1 mesh",
        "stage-1 mesh x2",
    ]
    amplitudes = {name: 0.1 * (k + 1) for k, name in enumerate(expected)}
    t = run.time
    te = (
        sum(
            a * np.sin(2 * math.pi * expected[name] * t + k) for k, (name, a) in enumerate(amplitudes.items())
        )
        * ARCSEC
    )
    synthetic = dataclasses.replace(run, te=te - 100.0 * ARCSEC)
    got = synthetic.excitation_amplitudes()
    assert [(name, hz) for name, hz, _ in got] == list(expected.items())
    for name, _hz, amplitude in got:
        assert amplitude == pytest.approx(amplitudes[name], rel=0.02), name
    coarse = dataclasses.replace(synthetic, step=1.0 / (1.5 * ex.pin_passing))
    assert dict((n, a) for n, _, a in coarse.excitation_amplitudes())["pin passing x2"] is None


def test_the_summary_and_json_carry_the_amplitudes(capsys):
    assert cli.main(["simulate", "RV-40E-121", "--load", "206", "--duration", "0.1", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    rows = data["excitations"]
    assert [set(r) for r in rows] == [{"name", "frequency_hz", "amplitude_arcsec", "not_resolved"}] * 8
    ex = dict(Excitations.at(run_design(), 1600.0).with_harmonics())
    assert {r["name"]: r["frequency_hz"] for r in rows} == pytest.approx(ex)
    # 0.1 s at speed resolves the 2nd orders of pin passing and mesh (0.0568 s needed), not the
    # others (0.113 s and more): those carry the reason instead of an amplitude
    assert {r["name"] for r in rows if r["not_resolved"] is None} == {"pin passing x2", "stage-1 mesh x2"}
    assert all((r["amplitude_arcsec"] is None) == (r["not_resolved"] is not None) for r in rows)
    assert all(r["amplitude_arcsec"] > 0.0 for r in rows if r["not_resolved"] is None)
    assert cli.main(["simulate", "RV-40E-121", "--load", "206", "--duration", "0.1"]) == 0
    out = capsys.readouterr().out
    assert "TE amplitude [arcsec]" in out and "stage-1 mesh x2" in out


def run_design():
    from rvfmu.core.reducer.design import preset

    return preset("RV-40E-121")
