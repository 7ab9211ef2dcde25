"""Sweeps on a Dask LocalCluster: the same rows as the CLI run task by task, resumable, and
complete when a worker dies in the middle."""

import json
import os
import signal
import subprocess
import sys

import pandas as pd
import pytest

from conftest import DEFAULT_SCENE, cli_compare
from test_api import measured, timed

from layertrace import sweep

distributed = pytest.importorskip("dask.distributed")


@pytest.fixture(scope="module")
def client():
    cluster = distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None)
    c = distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


def test_a_sweep_equals_the_sequential_cli_runs(tmp_path, client, fetched_scene):
    tasks = sweep.make_tasks([DEFAULT_SCENE, fetched_scene], ["ssr", "hssr"], {}, 96, 64, extra={"repeat": 1})
    paths = sweep.run_sweep(tasks, str(tmp_path), client, threads=1, progress=False)
    table = sweep.gather(paths, str(tmp_path))
    assert len(table) == 4
    assert os.path.exists(tmp_path / "results.csv") and os.path.exists(tmp_path / "results.png")
    csv = pd.read_csv(tmp_path / "results.csv")
    assert list(csv.columns[:2]) == ["scene", "camera"] and len(csv) == 4
    for scene in (DEFAULT_SCENE, fetched_scene):
        cli = cli_compare(tmp_path, scene, 96, 64, ["ssr", "hssr"], "--repeat", "1")
        for tracer in ("ssr", "hssr"):
            row = csv[(csv["scene"] == scene) & (csv["tracer"] == tracer)]
            assert len(row) == 1
            row = row.iloc[0]
            for key, want in cli["compare"][tracer].items():
                if isinstance(want, dict):
                    got = json.loads(row[key])
                    assert {k: v for k, v in got.items() if not timed(k)} == {k: v for k, v in want.items() if not timed(k)}, key
                elif not measured(key, tracer):
                    assert row[key] == pytest.approx(want, rel=1e-12), f"{scene} {tracer} {key}"
    # Resumable: every task has its file, so a second run runs nothing.
    stamps = {p: os.path.getmtime(p) for p in paths}
    sweep.run_sweep(tasks, str(tmp_path), client, progress=False)
    assert stamps == {p: os.path.getmtime(p) for p in paths}


def test_a_sweep_whose_worker_dies_completes_every_row(tmp_path, client):
    grid = {"hssr_tau": [2, 4, 8, 16, 25, 64]}
    tasks = sweep.make_tasks([DEFAULT_SCENE], ["hssr"], grid, 64, 48, extra={"repeat": 1})
    pids = client.run(os.getpid)
    killed = []

    def kill_one(path):
        if not killed:  # after the first result, kill a worker process outright; its nanny starts another
            worker, pid = next(iter(pids.items()))
            os.kill(pid, signal.SIGKILL)
            killed.append(worker)

    paths = sweep.run_sweep(tasks, str(tmp_path), client, threads=1, on_result=kill_one, progress=False)
    assert killed
    assert all(os.path.exists(p) for p in paths)
    table = sweep.gather(paths, str(tmp_path))
    assert sorted(table["hssr_tau"]) == grid["hssr_tau"]
    client.wait_for_workers(2, timeout=60)


def test_the_command_line(tmp_path):
    env = dict(os.environ)
    out = tmp_path / "cmd"
    args = [sys.executable, "-m", "layertrace.sweep", "--scene", DEFAULT_SCENE + ":low", "--tracers", "ssr,hssr", "--param", "hssr-tau=4,25",
            "--width", "64", "--height", "48", "--repeat", "1", "--workers", "2", "--quiet", "-o", str(out)]
    p = subprocess.run(args, capture_output=True, text=True, env=env)
    assert p.returncode == 0, p.stderr
    csv = pd.read_csv(out / "results.csv")
    assert len(csv) == 4 and set(csv["camera"]) == {"low"} and sorted(set(csv["hssr_tau"])) == [4, 25]
    bad = subprocess.run(args[:3] + ["--scene", str(tmp_path / "none.obj"), "-o", str(out)], capture_output=True, text=True, env=env)
    assert bad.returncode == 2 and "none.obj: file not found" in bad.stderr
    bad = subprocess.run(args[:3] + ["--scene", DEFAULT_SCENE, "--param", "hssr_tau", "-o", str(out)], capture_output=True, text=True, env=env)
    assert bad.returncode == 2 and "--param hssr_tau: must be NAME=v1,v2,..." in bad.stderr
