"""The Python API against the CLI and against the oracles (docs/python.md)."""

import math

import numpy as np
import pytest

import layertrace as lt
from conftest import DEFAULT_SCENE, cli_compare, run_cli


def timed(key: str) -> bool:
    """Measured times: equal only by chance between two runs."""
    return key.endswith("_ms")


def measured(key: str, tracer: str) -> bool:
    """Times, and the memory of Embree's BVH, whose parallel build allocates a little more or
    less from one run to the next (the CLI's own runs differ too)."""
    return timed(key) or (key == "memory_bytes" and tracer in ("embree", "hybrid"))


def assert_same_entry(row: dict, cli: dict, where: str) -> None:
    """Every key of the CLI's entry is in the row with the same value, measurements aside."""
    for key, want in cli.items():
        assert key in row, f"{where}: {key} missing"
        if measured(key, row["tracer"]):
            assert row[key] >= 0.0
        elif isinstance(want, dict):
            got = row[key]
            for k, v in want.items():
                if not timed(k):
                    assert got[k] == v, f"{where}: {key}.{k} {got[k]} != {v}"
        else:
            assert row[key] == pytest.approx(want, rel=0, abs=0) or (isinstance(want, float) and math.isnan(want) and math.isnan(row[key])), \
                f"{where}: {key} {row[key]} != {want}"


@pytest.mark.parametrize("which", ["default", "fetched"])
def test_compare_equals_the_cli(tmp_path, which, request):
    scene_path = DEFAULT_SCENE if which == "default" else request.getfixturevalue("fetched_scene")
    tracers = ["ssr", "hssr", "embree"]
    cli = cli_compare(tmp_path, scene_path, 96, 64, tracers, "--repeat", "1", "--hssr-tau", "12", "--threads", "1")
    scene = lt.load_scene(scene_path)
    whole = {}
    table = lt.compare(scene, scene.default_camera(), 96, 64, tracers=tracers, repeat=1, hssr_tau=12, threads=1, stats=whole)
    assert list(table["tracer"]) == tracers
    assert whole["parameters"] == cli["parameters"] and whole["threads"] == cli["threads"] == 1
    for _, row in table.iterrows():
        assert_same_entry(row.to_dict(), cli["compare"][row["tracer"]], f"{which} {row['tracer']}")
        assert row["embree_trace_ms"] == whole["reference"]["trace_ms"]
    assert cli["compare"]["hssr"]["rays"]["count"] > 0


def test_a_named_camera_and_a_custom_view_equal_the_cli(tmp_path):
    scene = lt.load_scene(DEFAULT_SCENE)
    assert set(scene.cameras) == {"main", "low"}
    cli = cli_compare(tmp_path, DEFAULT_SCENE, 80, 48, ["hssr"], "--repeat", "1", "--camera", "low")
    row = lt.compare(scene, scene.cameras["low"], 80, 48, tracers=["hssr"], repeat=1).iloc[0].to_dict()
    assert_same_entry(row, cli["compare"]["hssr"], "camera low")
    view = lt.Camera(eye=(0.5, 1.2, 2.0), target=(0.0, 0.5, -1.0), fov=50)
    cli = cli_compare(tmp_path, DEFAULT_SCENE, 80, 48, ["ssr"], "--repeat", "1", "--eye", "0.5,1.2,2", "--target", "0,0.5,-1", "--fov", "50")
    row = lt.compare(scene, view, 80, 48, tracers=["ssr"], repeat=1).iloc[0].to_dict()
    assert_same_entry(row, cli["compare"]["ssr"], "custom view")


def test_render_returns_the_image_and_the_statistics_of_the_cli(tmp_path):
    scene = lt.load_scene(DEFAULT_SCENE)
    image, stats = lt.render(scene, None, 120, 72, tracer="hssr", effect="ao", ao_samples=2, repeat=1, preset="paper")
    assert image.shape == (72, 120, 3) and image.dtype == np.float32
    assert np.isfinite(image).all() and image.max() > 0.0
    run_cli("render", DEFAULT_SCENE, "--width", 120, "--height", 72, "--tracer", "hssr", "--effect", "ao", "--ao-samples", 2, "--repeat", 1,
            "--preset", "paper", "--quiet", "-o", tmp_path / "r.png")
    import json

    with open(tmp_path / "r.json") as f:
        cli = json.load(f)
    assert stats["parameters"] == cli["parameters"] and stats["preset"] == "paper"
    for key in ("count", "hits", "iterations_mean"):
        assert stats["rays"][key] == cli["rays"][key], key
    assert stats["hssr"]["intervals_per_level"] == cli["hssr"]["intervals_per_level"]


def test_capture_layers_are_sorted_intervals_with_their_triangles():
    layers = lt.capture(DEFAULT_SCENE, None, 96, 64, k=4)
    assert layers.depth.shape == (64, 96, 4) and layers.normal.shape == (64, 96, 4, 3) and layers.count.shape == (64, 96)
    stored = np.arange(4)[None, None, :] < layers.count[..., None]
    assert (np.isfinite(layers.depth) == stored).all() and ((layers.triangle >= 0) == stored).all()
    d = layers.depth
    assert ((d[..., 1:] >= d[..., :-1]) | ~stored[..., 1:]).all(), "each pixel's layers are sorted front to back"
    assert (layers.back[stored] > layers.depth[stored]).all()
    assert np.allclose(np.linalg.norm(layers.normal[stored], axis=1), 1.0, atol=1e-3)
    with pytest.raises(ValueError):
        layers.depth[0, 0, 0] = 1.0  # read-only views of layertrace's memory
    levels = layers.pyramid(hssr_tau=25)
    assert levels[0]["intervals"].shape == (64, 96, 4, 2)
    assert all(lv["offset"][-1] == len(lv["intervals"]) for lv in levels[1:])


def test_trace_answers_camera_rays_with_the_front_layer_and_matches_the_exhaustive_march():
    layers = lt.capture(DEFAULT_SCENE, None, 96, 64)
    o, d = layers.pixel_rays()
    front = layers.triangle[..., 0].reshape(-1)
    covered = front >= 0
    for tracer in ("hssr", "ssr-layers", "hiz"):
        a = lt.trace(layers, o, d, tracer=tracer, from_surface=False)
        assert (a["triangle"][covered] == front[covered]).all(), tracer
        assert (a["layer"][covered] == 0).all(), tracer
    # The fragments' points lie on the camera rays at their depth.
    p = layers.positions(0).reshape(-1, 3)[covered]
    forward, _, _ = layers.camera.frame()
    assert np.allclose((p - o[covered]) @ forward, layers.depth[..., 0].reshape(-1)[covered], rtol=1e-5)
    # Reflection rays off every front fragment: HSSR answers each as the exhaustive march
    # (one level) does, hit for hit, in fewer steps.
    n = layers.world_normals(0).reshape(-1, 3)[covered]
    dn = d[covered]
    refl = dn - 2.0 * (dn * n).sum(1)[:, None] * n
    hssr = lt.trace(layers, p, refl, tracer="hssr")
    one = lt.trace(layers, p, refl, tracer="hssr", hssr_levels=1)
    assert (hssr["hit"] == one["hit"]).all() and (hssr["triangle"] == one["triangle"]).all()
    assert (hssr["pixel"] == one["pixel"]).all() and (hssr["layer"] == one["layer"]).all()
    assert hssr["iterations"].mean() < 0.6 * one["iterations"].mean(), "the hierarchy skips cells"
    # Rays of any length: a far depth that rounds to infinity still stops at the empty slots.
    far = lt.trace(layers, p, refl, tracer="hssr", max_distance=1e30)
    far_one = lt.trace(layers, p, refl, tracer="hssr", hssr_levels=1, max_distance=1e30)
    assert (far["hit"] == far_one["hit"]).all() and (far["triangle"] == far_one["triangle"]).all()
    assert (far_one["triangle"][far_one["hit"]] >= 0).all(), "no answer from an empty slot"
    assert hssr["hit"].mean() > 0.5
    # Embree, the geometric truth, on the same rays: a sanity bound on the screen-space answers
    # (0.77 of the rays both answer hit the same triangle here; the rest are what the layers
    # cannot know: docs/evaluation.md).
    embree = lt.trace(layers, p, refl, tracer="embree")
    both = hssr["hit"] & embree["hit"]
    assert (hssr["triangle"][both] == embree["triangle"][both]).mean() > 0.6


@pytest.mark.parametrize("kwargs,cli_args", [
    ({"hssr_tau": "many"}, ["--hssr-tau", "many"]),
    ({"tracer": "nope"}, ["--tracer", "nope"]),
    ({"no_such_option": 3}, ["--no-such-option", "3"]),
    ({"layers": 40}, ["--layers", "40"]),
    ({"effect": "glow"}, ["--effect", "glow"]),
])
def test_errors_carry_the_cli_message(tmp_path, kwargs, cli_args):
    status, _, err = run_cli("render", DEFAULT_SCENE, "--width", 32, "--height", 32, "--quiet", "-o", tmp_path / "x.png", *cli_args, check=False)
    assert status == 2
    with pytest.raises(ValueError) as e:
        lt.render(DEFAULT_SCENE, None, 32, 32, **kwargs)
    assert err.strip() == "layertrace: " + str(e.value)
    assert not (tmp_path / "x.png").exists()


def test_errors_of_the_python_side(tmp_path):
    status, _, err = run_cli("render", tmp_path / "missing.obj", "-o", tmp_path / "x.png", check=False)
    with pytest.raises(ValueError) as e:
        lt.load_scene(tmp_path / "missing.obj")
    assert status == 2 and err.strip() == "layertrace: " + str(e.value)
    layers = lt.capture(DEFAULT_SCENE, None, 32, 32)
    with pytest.raises(ValueError, match=r"origins: must have shape \(N, 3\)"):
        lt.trace(layers, np.zeros((4, 2)), np.zeros((4, 3)))
    with pytest.raises(ValueError, match=r"directions\[1\]: must be a finite, non-zero vector"):
        lt.trace(layers, np.zeros((2, 3)), np.array([[0, 0, -1], [0, 0, 0]]))
    with pytest.raises(ValueError, match="threads -1"):
        lt.render(DEFAULT_SCENE, None, 32, 32, threads=-1)
    with pytest.raises(TypeError):
        lt.render(DEFAULT_SCENE, "main", 32, 32)
