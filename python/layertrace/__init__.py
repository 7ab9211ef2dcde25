"""layertrace: image-space ray tracing through multi-layer fragment buffers, from Python.

The functions take numpy arrays and return numpy arrays, pandas tables and plain dicts. Every
option and parameter has the CLI's name with underscores (``hssr_tau=25`` is ``--hssr-tau 25``,
``layers=8`` is ``--layers 8``), the CLI's defaults and presets (``preset="paper"``), and the
CLI's checks: bad input raises ``ValueError`` with the line ``layertrace`` would print, a
failure inside layertrace raises ``RuntimeError``. The C++ work runs without the GIL.

    import layertrace as lt
    scene = lt.load_scene("scenes/default.json")
    image, stats = lt.render(scene, scene.default_camera(), 320, 180, tracer="hssr")
    table = lt.compare(scene, scene.default_camera(), 320, 180, tracers=["ssr", "hssr"])

See docs/python.md.
"""

import json
from dataclasses import dataclass
from typing import Dict, Optional, Sequence, Tuple

import numpy as np

from . import _layertrace as _native

__all__ = ["Camera", "Scene", "Layers", "load_scene", "capture", "trace", "render", "compare", "tracer_names"]


def _number(v) -> str:
    """A number as text that reads back to the same float (repr, not str's 6 digits)."""
    if isinstance(v, bool):
        raise TypeError("a flag, not a number")
    return repr(float(v)) if isinstance(v, float) else str(v)


def _flags(params: Dict[str, object]) -> list:
    """Keyword arguments as the CLI's flags: name_with_underscores=value -> --name-with-underscores value;
    True/False -> --name / --no-name; a list or tuple -> comma-separated values."""
    args = []
    for name, value in params.items():
        if value is None:
            continue
        flag = "--" + name.replace("_", "-")
        if isinstance(value, bool):
            args.append(flag if value else "--no-" + name.replace("_", "-"))
        elif isinstance(value, (list, tuple)):
            args += [flag, ",".join(_number(v) if not isinstance(v, str) else v for v in value)]
        else:
            args += [flag, value if isinstance(value, str) else _number(value)]
    return args


def _vec(name: str, v) -> Tuple[float, float, float]:
    t = tuple(float(x) for x in v)
    if len(t) != 3:
        raise ValueError(f"{name} {v!r}: must have three coordinates")
    return t


@dataclass(frozen=True)
class Camera:
    """A pinhole camera in the scene file's coordinates: the eye, the point looked at, the up
    direction and the vertical field of view in degrees. ``name`` is set for a camera of the
    scene (``Scene.cameras``), which the CLI's ``--camera NAME`` selects."""

    eye: Tuple[float, float, float]
    target: Tuple[float, float, float]
    up: Tuple[float, float, float] = (0.0, 1.0, 0.0)
    fov: float = 60.0
    name: Optional[str] = None
    default: bool = False  # the scene's default view: no view option at all, as the CLI without one

    def __init__(self, eye, target, up=(0.0, 1.0, 0.0), fov=60.0, name=None, default=False):
        object.__setattr__(self, "eye", _vec("eye", eye))
        object.__setattr__(self, "target", _vec("target", target))
        object.__setattr__(self, "up", _vec("up", up))
        object.__setattr__(self, "fov", float(fov))
        object.__setattr__(self, "name", name)
        object.__setattr__(self, "default", bool(default))

    def frame(self):
        """The camera's unit axes in the scene's coordinates: (forward, right, up)."""
        eye, target = np.array(self.eye), np.array(self.target)
        forward = (target - eye) / np.linalg.norm(target - eye)
        right = np.cross(forward, np.array(self.up))
        right /= np.linalg.norm(right)
        return forward, right, np.cross(right, forward)

    def _args(self) -> list:
        if self.default:
            return []
        if self.name is not None:
            return ["--camera", self.name]
        text = lambda v: ",".join(_number(x) for x in v)  # noqa: E731
        return ["--eye", text(self.eye), "--target", text(self.target), "--up", text(self.up), "--fov", _number(self.fov)]


def _camera(d: dict, **kw) -> Camera:
    return Camera(d["eye"], d["target"], d["up"], d["fov"], **kw)


class Scene:
    """A scene file as the CLI reads it (any model assimp reads, a Quake 3 ``.pk3`` or a JSON
    scene): its path, its named cameras and the view the CLI takes by default."""

    def __init__(self, path: str, info: dict):
        self.path = str(path)
        self.name = info["name"]
        self.triangles = info["triangles"]
        self.cameras: Dict[str, Camera] = {}
        for c in info["cameras"]:
            self.cameras.setdefault(c["name"], _camera(c, name=c["name"]))  # the first of a name, as --camera
        self._default = _camera(info["default_camera"], default=True)

    def default_camera(self) -> Camera:
        """The view of ``layertrace render SCENE`` without view options: the scene's first
        camera, else one framing the whole scene."""
        return self._default

    def __repr__(self):
        return f"Scene({self.path!r}, {self.triangles} triangles, cameras={list(self.cameras)})"


def load_scene(path) -> Scene:
    """Loads a scene (ValueError naming the file if it cannot be read)."""
    return Scene(path, _native.load_scene(str(path)))


def tracer_names() -> list:
    """Every tracer's name, as ``layertrace tracers`` lists them."""
    return _native.tracer_names().split(", ")


def _scene(scene) -> Scene:
    if isinstance(scene, str) or hasattr(scene, "__fspath__"):
        return load_scene(scene)
    if not isinstance(scene, Scene):
        raise TypeError("scene: a layertrace.Scene or a path")
    return scene


def _frame_args(command: str, scene: Scene, camera: Optional[Camera], width: int, height: int, params: dict) -> list:
    camera = camera if camera is not None else scene.default_camera()
    if not isinstance(camera, Camera):
        raise TypeError("camera: a layertrace.Camera or None (the scene's default view)")
    return [command, scene.path, "--width", str(int(width)), "--height", str(int(height)), "--quiet"] + camera._args() + _flags(params)


class Layers:
    """The k layers of one view (Hofmann et al. 2017, §4): per pixel the k front-most fragments,
    sorted by depth. ``depth`` and ``back`` are each fragment's interval [depth, depth +
    thickness] in scene units along the view direction, ``normal`` its camera-space normal,
    ``triangle`` the scene triangle (-1 for an empty slot, whose depth is NaN), ``count`` the
    slots used per pixel. The arrays are views of layertrace's memory (read-only)."""

    def __init__(self, native, scene: Scene, camera: Camera):
        self._native = native
        self.scene = scene
        self.camera = camera

    width = property(lambda self: self._native.width)
    height = property(lambda self: self._native.height)
    k = property(lambda self: self._native.k)
    depth = property(lambda self: _readonly(self._native.depth))
    back = property(lambda self: _readonly(self._native.back))
    normal = property(lambda self: _readonly(self._native.normal))
    triangle = property(lambda self: _readonly(self._native.triangle))
    count = property(lambda self: _readonly(self._native.count))

    def pixel_rays(self):
        """One ray from the eye through the centre of every pixel, row by row: (origins,
        directions), each (H·W, 3) in the scene's coordinates, the directions of unit length."""
        forward, right, up = self.camera.frame()
        h = np.tan(np.radians(self.camera.fov) / 2.0)
        ys, xs = np.mgrid[0:self.height, 0:self.width]
        x = ((xs + 0.5) / self.width * 2.0 - 1.0) * h * self.width / self.height
        y = (1.0 - (ys + 0.5) / self.height * 2.0) * h
        d = (forward + x[..., None] * right + y[..., None] * up).reshape(-1, 3)
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        return np.repeat(np.array(self.camera.eye)[None, :], len(d), axis=0), d

    def positions(self, layer: int = 0) -> np.ndarray:
        """The points of one layer's fragments in the scene's coordinates, (H, W, 3); NaN where
        a pixel has no fragment in that layer."""
        origins, d = self.pixel_rays()
        forward, _, _ = self.camera.frame()
        depth = self.depth[..., layer].reshape(-1)  # along the view direction
        return (origins + d * (depth / (d @ forward))[:, None]).reshape(self.height, self.width, 3)

    def world_normals(self, layer: int = 0) -> np.ndarray:
        """One layer's normals in the scene's coordinates, (H, W, 3); NaN where empty."""
        forward, right, up = self.camera.frame()
        n = self.normal[..., layer, :]
        return n[..., :1] * right + n[..., 1:2] * up - n[..., 2:] * forward

    def pyramid(self, **params) -> list:
        """The interval pyramid over these layers (Hofmann et al. 2017, §4.3) for the
        parameters given (``hssr_tau``, ``hssr_levels``, …): one dict per level with its
        ``width``, ``height`` and ``intervals`` ((H, W, k, 2) at level 0; (n, 2) with the CSR
        ``offset`` of every cell above it)."""
        args = ["render", self.scene.path, "--width", str(self.width), "--height", str(self.height)] + _flags(params)
        return self._native.pyramid(args)


def _readonly(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


def capture(scene, camera: Optional[Camera], width: int, height: int, k: int = 4, device: str = "cpu", threads: int = 0,
            **params) -> Layers:
    """Rasterizes every fragment of the view into per-pixel lists and keeps the k front-most
    (``layertrace layers``' capture; ``device="gpu"`` captures with OpenGL). Frame options go as
    keyword arguments (``thickness_px=2``, ``front_faces_only=True``, …)."""
    scene = _scene(scene)
    camera = camera if camera is not None else scene.default_camera()
    args = _frame_args("render", scene, camera, width, height, dict(params, layers=k))
    return Layers(_native.Layers(args, device, int(threads)), scene, camera)


def trace(layers: Layers, origins, directions, tracer: str = "hssr", from_surface: bool = True, max_distance: float = 0.0,
          threads: int = 0, **params) -> dict:
    """Traces rays through ``layers`` with one tracer. ``origins`` and ``directions`` are (N, 3)
    arrays in the scene file's coordinates. ``from_surface``: the rays leave a stored surface (a
    reflection, AO or shadow ray), so the image-space tracers skip their first pixel
    (Hofmann et al. 2017, §5.1); False for rays from free space. ``max_distance``: where the
    rays end, in scene units (0: the scene's diagonal, as the CLI's ``--max-distance``). Returns a dict of arrays:
    ``hit`` (bool), ``t`` (distance to the hit, inf for a miss), ``pixel`` ((N, 2) x, y of the
    hit fragment; -1 for geometric tracers without one), ``layer``, ``triangle`` (-1 for a miss)
    and ``iterations``."""
    if not isinstance(layers, Layers):
        raise TypeError("layers: the result of layertrace.capture")
    o = np.ascontiguousarray(origins, dtype=np.float32)
    d = np.ascontiguousarray(directions, dtype=np.float32)
    args = ["render", layers.scene.path, "--width", str(layers.width), "--height", str(layers.height), "--tracer", tracer] + _flags(params)
    return layers._native.trace(o, d, tracer, args, bool(from_surface), float(max_distance), int(threads))


def render(scene, camera: Optional[Camera], width: int, height: int, tracer: str = "hssr", effect: str = "reflection",
           device: str = "cpu", threads: int = 0, **params):
    """``layertrace render``: one effect traced with one tracer. Returns ``(image, stats)``: an
    (H, W, 3) float32 linear image and the statistics ``render`` writes, as a dict."""
    args = _frame_args("render", _scene(scene), camera, width, height,
                       dict(params, tracer=tracer, effect=effect, device=device, threads=int(threads) or None))
    image, stats = _native.render(args, int(threads))
    return image, json.loads(stats)


def compare(scene, camera: Optional[Camera], width: int, height: int, tracers: Sequence[str] = ("ssr", "ssr-layers", "hssr"),
            effect: str = "reflection", device: str = "cpu", threads: int = 0, stats: Optional[dict] = None,
            images: Optional[dict] = None, **params):
    """``layertrace compare``: the same rays through every tracer and Embree. Returns a pandas
    DataFrame with one row per tracer: ``tracer``, then the keys of that tracer's entry in
    ``compare.json`` under the same names (``correct_hit``, ``wrong_hit``, ``false_miss``,
    ``trace_ms``, ``iterations_mean``, ``psnr_db``, …; nested entries such as ``rays`` stay
    dicts), plus ``embree_trace_ms``. Pass a dict as ``stats`` to receive the whole
    ``compare.json`` as well, and one as ``images`` to receive compare's images as (H, W, 3)
    float32 arrays by the names of its files without ``.png``: ``reference``, ``hssr``,
    ``hssr_traced``, ``hssr_classes`` (the strict classes, coloured as docs/evaluation.md
    shows), ``side_by_side``, …"""
    import pandas as pd

    if isinstance(tracers, str):
        tracers = [tracers]
    args = _frame_args("compare", _scene(scene), camera, width, height,
                       dict(params, tracers=list(tracers), effect=effect, device=device, threads=int(threads) or None))
    text, pictures = _native.compare(args, int(threads))
    whole = json.loads(text)
    if stats is not None:
        stats.update(whole)
    if images is not None:
        images.update(pictures)
    rows = []
    for name in tracers:
        row = {"tracer": name}
        row.update(whole["compare"][name])
        row["embree_trace_ms"] = whole["reference"]["trace_ms"]
        rows.append(row)
    return pd.DataFrame(rows)
