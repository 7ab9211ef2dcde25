"""Shared fixtures: the CLI beside the package, the source tree's scenes and a run helper."""

import json
import os
import subprocess

import pytest

SOURCE = os.environ.get("LAYERTRACE_SOURCE", os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..")))
CLI = os.environ.get("LAYERTRACE_CLI", os.path.join(SOURCE, "build", "layertrace"))
DEFAULT_SCENE = os.path.join(SOURCE, "scenes", "default.json")
FETCHED_SCENE = os.path.join(SOURCE, "data", "models", "teapots.DAE")  # scripts/fetch-scenes.sh


def run_cli(*args, check=True):
    """Runs the CLI; returns (exit status, stdout, stderr)."""
    p = subprocess.run([CLI, *map(str, args)], capture_output=True, text=True)
    if check and p.returncode != 0:
        raise AssertionError(f"layertrace {' '.join(map(str, args))} failed ({p.returncode}): {p.stderr}")
    return p.returncode, p.stdout, p.stderr


def cli_compare(tmp_path, scene, width, height, tracers, *extra):
    """The CLI's compare.json for the same frame."""
    out = tmp_path / ("cli-" + os.path.basename(scene) + "-" + "-".join(tracers))
    run_cli("compare", scene, "--width", width, "--height", height, "--tracers", ",".join(tracers), "--quiet", "-o", out, *extra)
    with open(out / "compare.json") as f:
        return json.load(f)


@pytest.fixture
def fetched_scene():
    if not os.path.exists(FETCHED_SCENE):
        pytest.skip(f"{FETCHED_SCENE} not fetched (scripts/fetch-scenes.sh)")
    return FETCHED_SCENE
