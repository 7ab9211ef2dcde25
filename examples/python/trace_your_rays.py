"""Captures a view's k layers and traces rays of your own through them: one reflection ray off
every pixel's front fragment, with HSSR and with Embree, and counts where they agree.

    PYTHONPATH=build/python python3 examples/python/trace_your_rays.py SCENE
"""
import math
import sys

import numpy as np

import layertrace as lt

scene = lt.load_scene(sys.argv[1] if len(sys.argv) > 1 else "scenes/default.json")
W, H = 320, 180
layers = lt.capture(scene, scene.default_camera(), W, H, k=4)
print(f"{layers.k} layers, {int(layers.count.sum())} fragments kept, up to {layers.count.max()} per pixel")

# The camera's frame, to turn pixels and camera-space normals into scene coordinates.
c = layers.camera
eye, target, up = np.array(c.eye), np.array(c.target), np.array(c.up)
forward = (target - eye) / np.linalg.norm(target - eye)
right = np.cross(forward, up)
right /= np.linalg.norm(right)
true_up = np.cross(right, forward)
h = math.tan(math.radians(c.fov) / 2)
ys, xs = np.mgrid[0:H, 0:W]
view = forward + (((xs + 0.5) / W * 2 - 1) * h * W / H)[..., None] * right + ((1 - (ys + 0.5) / H * 2) * h)[..., None] * true_up
view = (view / np.linalg.norm(view, axis=2, keepdims=True)).reshape(-1, 3)

covered = layers.count.reshape(-1) > 0
depth = layers.depth[..., 0].reshape(-1)[covered]  # along the view direction
n = layers.normal[..., 0, :].reshape(-1, 3)[covered]  # camera space: x right, y up, -z forward
normal = n[:, :1] * right + n[:, 1:2] * true_up - n[:, 2:] * forward
d = view[covered]
origins = eye + d * (depth / (d @ forward))[:, None]
directions = d - 2 * (d * normal).sum(1, keepdims=True) * normal

hssr = lt.trace(layers, origins, directions, tracer="hssr", hssr_tau=25)
embree = lt.trace(layers, origins, directions, tracer="embree")
same = (hssr["hit"] == embree["hit"]) & (hssr["triangle"] == embree["triangle"])
print(f"{len(origins)} rays: HSSR hits {hssr['hit'].mean():.1%} in {hssr['iterations'].mean():.1f} iterations per ray; "
      f"the same answer as Embree for {same.mean():.1%}")
