"""Renders one-bounce reflections with HSSR, compares SSR and HSSR against Embree on the same
rays, and saves the table and the strict-class images of both.

    PYTHONPATH=build/python python3 examples/python/render_and_compare.py SCENE [OUT]
"""
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import layertrace as lt  # noqa: E402

scene = lt.load_scene(sys.argv[1] if len(sys.argv) > 1 else "scenes/default.json")
out = sys.argv[2] if len(sys.argv) > 2 else "out/python"
os.makedirs(out, exist_ok=True)
camera = scene.default_camera()

image, stats = lt.render(scene, camera, 320, 180, tracer="hssr", effect="reflection")
print(f"{scene.name}: {stats['rays']['count']} reflection rays, {stats['rays']['iterations_mean']:.1f} HSSR iterations per ray")
plt.imsave(os.path.join(out, "hssr_reflection.png"), np.clip(image, 0.0, 1.0) ** (1 / 2.2))

images = {}
table = lt.compare(scene, camera, 320, 180, tracers=["ssr", "hssr"], images=images)
print(table[["tracer", "correct_hit", "wrong_hit", "false_miss", "iterations_mean", "trace_ms", "embree_trace_ms"]].to_string(index=False))
table.to_csv(os.path.join(out, "compare.csv"), index=False)

fig, axes = plt.subplots(1, 2, figsize=(10, 3.2))
for ax, name in zip(axes, ["ssr", "hssr"]):
    ax.imshow(images[name + "_classes"])
    ax.set_title(f"{name}: strict classes against Embree")
    ax.axis("off")
fig.tight_layout()
fig.savefig(os.path.join(out, "classes.png"), dpi=100)
print(f"wrote {out}/hssr_reflection.png, compare.csv and classes.png")
