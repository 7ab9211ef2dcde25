"""Captures a view's k layers and traces rays of your own through them: one reflection ray off
every pixel's front fragment, with HSSR and with Embree, and counts where they agree.

    PYTHONPATH=build/python python3 examples/python/trace_your_rays.py SCENE
"""
import sys

import layertrace as lt

scene = lt.load_scene(sys.argv[1] if len(sys.argv) > 1 else "scenes/default.json")
W, H = 320, 180
layers = lt.capture(scene, scene.default_camera(), W, H, k=4)
print(f"{layers.k} layers, {int(layers.count.sum())} fragments kept, up to {layers.count.max()} per pixel")

# One reflection ray off every covered pixel's front fragment, in the scene's coordinates.
covered = layers.count.reshape(-1) > 0
_, view = layers.pixel_rays()
origins = layers.positions(0).reshape(-1, 3)[covered]
normal = layers.world_normals(0).reshape(-1, 3)[covered]
d = view[covered]
directions = d - 2 * (d * normal).sum(1, keepdims=True) * normal

hssr = lt.trace(layers, origins, directions, tracer="hssr", hssr_tau=25)
embree = lt.trace(layers, origins, directions, tracer="embree")
same = (hssr["hit"] == embree["hit"]) & (hssr["triangle"] == embree["triangle"])
print(f"{len(origins)} rays: HSSR hits {hssr['hit'].mean():.1%} in {hssr['iterations'].mean():.1f} iterations per ray; "
      f"the same answer as Embree for {same.mean():.1%}")
