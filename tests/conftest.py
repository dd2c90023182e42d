"""Shared fixtures: the presets and the seed 002 error set.

`rv40` is the RV-40E-121 as the seeds and the formulas give it (the preset before its
calibration to the catalogue, `RV-40E-121-estimate`), its crank bearings and its pins linear
springs of their stated stiffness: the tests of the physics were built on that geometry and
those stiffnesses.  The calibrated presets and the series compliance
that calibration adds are tested on their own (test_catalogue.py), exactly.  `rv40_rollers` is
the estimate with its crank bearings' rollers given, its pins linear: those bearings follow
the roller law (rvfmu/core/laws/roller_law.py).  `rv40_hertz` is the estimate as shipped, its
pins' groove given too: the pins follow the Hertz law (rvfmu/core/laws/pin_law.py).
"""

import tempfile
from pathlib import Path

import numpy as np
import pytest

from rvfmu.core.reducer.design import preset
from rvfmu.core.reducer.errors import load_errors

ROOT = Path(__file__).resolve().parent.parent

# The test files that take longest (a minute or more each on a 2-core AMD EPYC: allocations,
# hosts under valgrind, FMU builds, the studies' backends), run first.  On every core
# (pytest-xdist, --dist loadfile: each file on one worker) the files go out in this order, so
# the long ones start at once instead of leaving one worker alone at the end.
LONG_FIRST = (
    "test_allocate_rv40e.py",
    "test_hardening_fmu.py",
    "test_allocate.py",
    "test_linearized_sobol.py",
    "test_fmu.py",
    "test_hardening_studies.py",
    "test_law_forms.py",
    "test_tolerance_runs.py",
    "test_catalogue.py",
    "test_fmu_native3.py",
    "test_fmu_native.py",
    "test_readme.py",
)


def pytest_collection_modifyitems(items):
    """The files of LONG_FIRST first, in that order, then the others as collected (each file's
    tests keep their order)."""
    rank = {name: k for k, name in enumerate(LONG_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(LONG_FIRST)))


@pytest.fixture(scope="session", autouse=True)
def temporary_files_in_the_runs_folder(tmp_path_factory):
    """The suite's temporary files, and those of the processes it starts, in pytest's own
    folder of this run (pytest keeps the last three runs' folders): fmpy leaves the FMU it
    unpacked in the temporary folder after every simulation that raised, 17 MB for the
    pythonfmu FMU, about 2 GB a run of the suite that no run removed.  The user's cache
    folder too ($XDG_CACHE_HOME), where the pythonfmu FMU keeps a copy of its rvfmu package
    for the hosts the suite starts (`rvfmu.fmu.slave.stable_bundle`)."""
    folder = str(tmp_path_factory.mktemp("tmp"))
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("TMPDIR", folder)
        patch.setenv("XDG_CACHE_HOME", str(tmp_path_factory.mktemp("cache")))
        patch.setattr(tempfile, "tempdir", folder)
        yield


@pytest.fixture(scope="session")
def rv40():
    return linear_bearings(preset("RV-40E-121-estimate"))


def linear_bearings(design):
    """`design` with its crank bearings and its pins as linear springs of their stated
    stiffness (no rollers and no pin groove given: no roller law, no Hertz law)."""
    return linear_pins(design).with_fields(needle_rollers=0, tapered_rollers=0)


def linear_pins(design):
    """`design` with its pins as linear springs of their stated stiffness (no groove given)."""
    return design.with_fields(pin_groove_clearance=0.0)


@pytest.fixture(scope="session")
def rv40_rollers():
    return linear_pins(preset("RV-40E-121-estimate"))


@pytest.fixture(scope="session")
def rv40_hertz():
    return preset("RV-40E-121-estimate")


@pytest.fixture(scope="session")
def seed002(rv40):
    return load_errors(ROOT / "studies" / "seed002_errors.toml", rv40)


def unit(angle):
    return np.stack([np.cos(angle), np.sin(angle)], axis=-1)


def perp(v):
    return np.stack([-v[..., 1], v[..., 0]], axis=-1)


def hand_pin_geometry(design, theta_in):
    """Pin contact normals and closing rates from the kinematics of docs/model.md section 2, by hand.

    Returns normal (A, 2, z_p, 2), pin centre (z_p, 2), closing rate (A, 2, z_p): the
    rate at which each pin's interference grows per radian the carrier turns BACK
    with the input held (disc centre moves e*(1 + z_s/z_pl) per radian along the
    tangent of its eccentric direction, disc turns with the carrier).
    """
    d = design
    theta_out = theta_in / d.ratio
    psi = -d.z_c * theta_out[:, None] + np.array([0.0, np.pi])
    centre = d.e * unit(psi)  # (A, 2, 2)
    pitch = d.z_p * d.e * unit(psi)
    pins = d.R_p * unit(2 * np.pi * np.arange(d.z_p) / d.z_p)  # (z_p, 2)
    normal = pins[None, None] - pitch[:, :, None]
    normal /= np.linalg.norm(normal, axis=-1, keepdims=True)
    contact = pins[None, None] - d.r_rp * normal
    speed = d.e * (1.0 + d.z_s / d.z_pl)
    # carrier turning back: rotation -1, centre moves -speed along the tangent
    u = -speed * perp(unit(psi))[:, :, None, :] - perp(contact - centre[:, :, None])
    rate = np.einsum("ajkx,ajkx->ajk", normal, u)
    return normal, pins, rate
