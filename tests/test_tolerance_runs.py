"""Running studies: backends give identical results, work survives a kill, nothing is mixed."""

import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from tolerance_toy import write_study

from rvfmu.core.base.checks import InputError
from tolerance import montecarlo, run_mc
from tolerance.backends import DaskBackend
from tolerance.study import load_study

ROOT = Path(__file__).resolve().parent.parent
SUMMARY = re.compile(r"(\d+) batches of \d+ \((\d+) reused, (\d+) computed\)")


@pytest.fixture(scope="module")
def toy(tmp_path_factory):
    """A toy study and its in-process Monte Carlo (32 reducers, 4 batches)."""
    folder = tmp_path_factory.mktemp("toy")
    path = write_study(folder)
    return path, run_mc(path, output=folder / "inprocess")


def test_in_process_run_writes_batches_and_reports(toy):
    path, result = toy
    out = path.parent / "inprocess"
    assert result.Y.shape == (32, 2) and np.all(np.isfinite(result.Y)) and result.converged.all()
    names = sorted(p.name for p in (out / "mc").glob("*.parquet"))
    assert [name[:26] for name in names] == [f"batch-{s:09d}-{s + 8:09d}-" for s in range(0, 32, 8)]
    for name in (
        "manifest.json",
        "inputs.json",
        "study.toml",
        "mc_summary.json",
        "mc_samples.csv",
        "mc_distribution.png",
        "mc_worst_te.png",
        "mc_worst_te.csv",
        "mc_worst_errors.toml",
    ):
        assert (out / name).is_file(), name
    worst = result.analysis.worst
    assert result.worst_curve.te_pp_arcsec[0] == pytest.approx(result.Y[worst, 0], rel=1e-9)
    assert result.Y[worst, 0] == result.Y[:, 0].max()


def test_same_seed_gives_identical_results_on_every_backend(toy, tmp_path):
    path, reference = toy
    processes = run_mc(path, output=tmp_path / "processes", processes=2, plots=False)
    assert processes.computed.backend == "2 worker processes"
    np.testing.assert_array_equal(processes.Y, reference.Y)
    with DaskBackend(workers=2) as cluster:  # --workers 2: a LocalCluster
        local = list(
            cluster.map(
                load_study(path), ((b, montecarlo.rows(load_study(path), *b)) for b in [(0, 8), (8, 16)])
            )
        )
        address = cluster.client.scheduler.address
        remote = run_mc(path, output=tmp_path / "dask", scheduler=address, plots=False)
    assert remote.computed.backend == f"Dask cluster at {address} (2 workers)"
    np.testing.assert_array_equal(remote.Y, reference.Y)
    np.testing.assert_array_equal(remote.converged, reference.converged)
    for (start, stop), _, Y, _ in local:
        np.testing.assert_array_equal(Y, reference.Y[start:stop])
    # Same results, same bytes: the batch files (named by their sha256) are the same files.
    names = [
        sorted(p.name for p in (folder / "mc").glob("*.parquet"))
        for folder in (path.parent / "inprocess", tmp_path / "processes", tmp_path / "dask")
    ]
    assert len(names[0]) == 4 and names[0] == names[1] == names[2]


def test_a_run_again_computes_only_what_is_missing(toy, tmp_path):
    path, reference = toy
    out = tmp_path / "grow"
    shutil.copytree(path.parent / "inprocess", out)
    for batch in sorted((out / "mc").glob("*.parquet"))[2:]:
        batch.unlink()
    lines = []
    again = run_mc(path, n=48, output=out, log=lines.append, plots=False)
    assert SUMMARY.search(lines[-1]).groups() == ("6", "2", "4")
    np.testing.assert_array_equal(again.Y[:32], reference.Y)
    # A changed spec changes no computed number: every batch is reused.
    changed = write_study(tmp_path, name="toy", spec={"te_pp_arcsec": 12.0})
    lines.clear()
    respec = run_mc(changed, n=48, output=out, log=lines.append, plots=False)
    assert SUMMARY.search(lines[-1]).groups() == ("6", "6", "0")
    assert respec.analysis.yields[0].label == "te_pp_arcsec <= 12"


def test_a_killed_run_resumes_and_matches_an_uninterrupted_one(tmp_path):
    # 720 points per revolution: each batch of 16 takes a noticeable fraction of a second.
    path = write_study(tmp_path, study={"batch_size": 16}, operating={"points": 720}, montecarlo={"n": 96})
    out = tmp_path / "killed"
    command = [sys.executable, "-m", "rvfmu.cli", "mc", str(path), "-o", str(out), "--no-plots"]
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    first = subprocess.Popen(command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 60
    while not list((out / "mc").glob("batch-*.parquet")):
        assert first.poll() is None, first.stderr.read().decode()
        assert time.monotonic() < deadline, "no batch written in 60 s"
        time.sleep(0.002)
    first.send_signal(signal.SIGKILL)
    first.wait()
    first.stderr.close()
    assert first.returncode == -signal.SIGKILL
    written = len(list((out / "mc").glob("batch-*.parquet")))
    assert 1 <= written < 6
    second = subprocess.run(command, env=env, capture_output=True, text=True, timeout=120)
    assert second.returncode == 0, second.stderr
    batches, reused, computed = map(int, SUMMARY.search(second.stderr).groups())
    assert (batches, reused, computed) == (6, written, 6 - written)
    resumed = run_mc(path, output=out, plots=False)  # everything is there now
    assert resumed.computed.computed == 0
    uninterrupted = run_mc(path, output=tmp_path / "straight", plots=False)
    np.testing.assert_array_equal(resumed.Y, uninterrupted.Y)


def children(pid: int) -> set:
    """PIDs of the live processes whose parent is `pid` (from /proc)."""
    found = set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == pid and fields[0] != "Z":
            found.add(int(stat.parent.name))
    return found


@pytest.mark.skipif(not Path("/proc/self/stat").exists(), reason="needs Linux /proc to list processes")
def test_the_worker_processes_of_a_killed_run_end_with_it(tmp_path):
    """SIGKILL runs no clean-up: the pool's spawned workers must notice and exit by themselves."""
    path = write_study(tmp_path, study={"batch_size": 16}, operating={"points": 720}, montecarlo={"n": 4096})
    out = tmp_path / "killed"
    command = [
        sys.executable,
        "-m",
        "rvfmu.cli",
        "mc",
        str(path),
        "-o",
        str(out),
        "--no-plots",
        "--processes",
        "2",
    ]
    run = subprocess.Popen(
        command,
        env={**os.environ, "PYTHONPATH": str(ROOT)},
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    deadline = time.monotonic() + 120
    while not list((out / "mc").glob("batch-*.parquet")):  # the pool is up and working
        assert run.poll() is None and time.monotonic() < deadline
        time.sleep(0.05)
    workers = children(run.pid)
    assert len(workers) >= 2  # the two workers (and the resource tracker)
    run.send_signal(signal.SIGKILL)
    run.wait()
    deadline = time.monotonic() + 30
    alive = workers
    while alive and time.monotonic() < deadline:
        time.sleep(0.2)
        alive = {
            pid
            for pid in workers
            if Path(f"/proc/{pid}").exists()
            and Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] != "Z"
        }
    assert not alive, f"workers {sorted(alive)} outlived the killed run"


def test_a_corrupted_or_truncated_batch_is_refused_by_name(toy, tmp_path):
    path, _ = toy
    for damage in ("truncate", "flip"):
        out = tmp_path / damage
        shutil.copytree(path.parent / "inprocess", out)
        batch = sorted((out / "mc").glob("*.parquet"))[1]
        data = bytearray(batch.read_bytes())
        if damage == "truncate":
            data = data[: len(data) // 2]
        else:
            data[len(data) // 3] ^= 0x40
        batch.write_bytes(bytes(data))
        with pytest.raises(InputError, match="corrupted") as info:
            run_mc(path, output=out, plots=False)
        assert info.value.value == str(batch)


def test_an_output_folder_of_another_study_is_refused(toy, tmp_path):
    path, _ = toy
    other = write_study(tmp_path, name="other", tolerances={"carrier_assembly": {"position_um": 5.0}})
    with pytest.raises(InputError, match="belongs to another study .*differing in: factor_order, tolerances"):
        run_mc(other, output=path.parent / "inprocess")
    stranger = tmp_path / "stranger"
    stranger.mkdir()
    (stranger / "notes.txt").write_text("mine")
    with pytest.raises(InputError, match="is not empty and has no manifest.json"):
        run_mc(path, output=stranger)
