"""Evaluation sweeps on Dask distributed: scenes x cameras x tracers x parameter grids.

    python3 -m layertrace.sweep --scene scenes/default.json --scene data/models/sponza.obj:main \\
        --tracers ssr,hssr --param hssr_tau=4,25 --width 320 --height 180 -o out/sweep

Every (scene, camera, tracer, parameters) is one task: ``layertrace.compare`` of that tracer
alone, written to ``OUT/tasks/<key>.json`` when it finishes. A task whose JSON exists is not run
again, so an interrupted sweep resumes where it stopped; a task on a worker that dies is run
again elsewhere (Dask retries it) and loses no finished result. At the end the JSON files are
gathered into ``OUT/results.csv`` (one row per task: ``scene``, ``camera``, the parameters, and
the columns of ``layertrace.compare``) and ``OUT/results.png``.

By default the tasks run on a LocalCluster of this machine (``--workers``); with ``--scheduler
tcp://HOST:8786`` on a cluster started with ``dask-scheduler`` and ``dask-worker`` (docs/python.md).
"""

import argparse
import hashlib
import itertools
import json
import os
import sys
import tempfile
import time
from typing import Callable, Dict, List, Optional, Sequence

__all__ = ["Task", "make_tasks", "run_task", "run_sweep", "gather", "main"]


class Task(dict):
    """One task: scene (the path given), camera (a name, or "" for the scene's default view),
    tracer, params (name -> value), and the frame's width, height and effect."""

    @property
    def key(self) -> str:
        """A file name that identifies the task: readable, and unique through a hash of all of it."""
        text = json.dumps(self, sort_keys=True)
        digest = hashlib.sha1(text.encode()).hexdigest()[:12]
        base = os.path.splitext(os.path.basename(self["scene"]))[0]
        cam = self["camera"] or "default"
        return f"{base}-{cam}-{self['tracer']}-{digest}".replace(os.sep, "_").replace(":", "_")


def _value(text: str):
    """A parameter value from the command line: an int, a float, true/false, or the text."""
    low = text.lower()
    if low in ("true", "false"):
        return low == "true"
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    return text


def parse_scene(spec: str):
    """PATH[:CAMERA] -> (path, camera or ""). A path that exists as given keeps its colons."""
    if ":" in spec and not os.path.exists(spec):
        path, camera = spec.rsplit(":", 1)
        return path, camera
    return spec, ""


def parse_param(spec: str):
    """NAME=v1,v2,... -> (name, [values]); the name as the CLI's flag without dashes, - or _."""
    if "=" not in spec:
        raise ValueError(f"--param {spec}: must be NAME=v1,v2,...")
    name, values = spec.split("=", 1)
    name = name.strip().lstrip("-").replace("-", "_")
    vals = [_value(v.strip()) for v in values.split(",") if v.strip()]
    if not name or not vals:
        raise ValueError(f"--param {spec}: must be NAME=v1,v2,...")
    return name, vals


def make_tasks(scenes: Sequence[str], tracers: Sequence[str], params: Dict[str, list], width: int, height: int,
               effect: str = "reflection", extra: Optional[dict] = None) -> List[Task]:
    """Every combination of scene (PATH[:CAMERA]), tracer and parameter values."""
    names = sorted(params)
    tasks = []
    for spec in scenes:
        path, camera = parse_scene(spec)
        for tracer in tracers:
            for combo in itertools.product(*(params[n] for n in names)):
                tasks.append(Task(scene=path, camera=camera, tracer=tracer, params=dict(zip(names, combo)), width=int(width),
                                  height=int(height), effect=effect, extra=dict(extra or {})))
    return tasks


def run_task(task: Task, out_dir: str, threads: int = 0) -> str:
    """Runs one task (in a worker) and writes its JSON atomically; returns the file's path. A
    task whose JSON exists is not run again."""
    import layertrace as lt

    path = os.path.join(out_dir, "tasks", task.key + ".json")
    if os.path.exists(path):
        return path
    scene = lt.load_scene(task["scene"])
    if task["camera"]:
        if task["camera"] not in scene.cameras:
            raise ValueError(f"--scene {task['scene']}:{task['camera']}: no such camera (has: {', '.join(scene.cameras) or 'none'})")
        camera = scene.cameras[task["camera"]]
    else:
        camera = scene.default_camera()
    table = lt.compare(scene, camera, task["width"], task["height"], tracers=[task["tracer"]], effect=task["effect"], threads=threads,
                       **task["params"], **task.get("extra", {}))
    row = table.iloc[0].to_dict()
    record = {"task": dict(task), "row": row}
    os.makedirs(os.path.dirname(path), exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=os.path.dirname(path), suffix=".tmp")
    with os.fdopen(fd, "w") as f:
        json.dump(record, f, default=float)
    os.replace(tmp, path)
    return path


def _progress(done: int, total: int, start: float, stream=sys.stderr) -> None:
    width = 30
    filled = int(width * done / total) if total else width
    elapsed = time.time() - start
    stream.write(f"\rsweep [{'#' * filled}{'.' * (width - filled)}] {done}/{total} tasks, {elapsed:.0f} s")
    stream.flush()


def run_sweep(tasks: Sequence[Task], out_dir: str, client=None, threads: int = 0, retries: int = 3,
              on_result: Optional[Callable[[str], None]] = None, progress: bool = True) -> List[str]:
    """Runs the tasks that have no JSON yet on `client` (a dask.distributed Client), each at most
    1 + `retries` times, and returns every task's JSON path. `on_result` is called with each
    path as it arrives."""
    from dask.distributed import as_completed

    os.makedirs(os.path.join(out_dir, "tasks"), exist_ok=True)
    paths = [os.path.join(out_dir, "tasks", t.key + ".json") for t in tasks]
    todo = [t for t, p in zip(tasks, paths) if not os.path.exists(p)]
    start = time.time()
    done = len(tasks) - len(todo)
    if progress:
        _progress(done, len(tasks), start)
    if todo:
        futures = [client.submit(run_task, t, os.path.abspath(out_dir), threads, key=f"layertrace-{t.key}", retries=retries, pure=False)
                   for t in todo]
        for future in as_completed(futures):
            path = future.result()  # a task that failed every try raises here, naming its error
            done += 1
            if on_result:
                on_result(path)
            if progress:
                _progress(done, len(tasks), start)
    if progress:
        sys.stderr.write("\n")
    return paths


def gather(paths: Sequence[str], out_dir: str):
    """The tasks' JSON files as one table: OUT/results.csv and a plot, OUT/results.png. Returns
    the pandas DataFrame."""
    import pandas as pd

    rows = []
    for p in paths:
        with open(p) as f:
            record = json.load(f)
        task, row = record["task"], record["row"]
        flat = {"scene": task["scene"], "camera": task["camera"] or "default"}
        flat.update(task["params"])
        flat.update({k: (json.dumps(v) if isinstance(v, (dict, list)) else v) for k, v in row.items()})
        rows.append(flat)
    table = pd.DataFrame(rows)
    csv = os.path.join(out_dir, "results.csv")
    table.to_csv(csv + ".tmp", index=False)
    os.replace(csv + ".tmp", csv)
    _plot(table, os.path.join(out_dir, "results.png"))
    return table


def _plot(table, path: str) -> None:
    """Accuracy against cost: each task's share of correct hits over its trace time relative to
    Embree's on the same rays, one marker per tracer. Skipped without matplotlib."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return
    fig, ax = plt.subplots(figsize=(6.4, 4.2))
    for tracer, group in table.groupby("tracer"):
        ratio = group["trace_ms"] / group["embree_trace_ms"].where(group["embree_trace_ms"] > 0)
        ax.scatter(ratio, 100.0 * (group["correct_hit"] + group["correct_miss"]), label=tracer)
    ax.set_xlabel("trace time / Embree's on the same rays")
    ax.set_ylabel("rays answered as Embree does (%)")
    ax.set_title(f"layertrace sweep: {len(table)} tasks")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(path + ".tmp.png", dpi=110)
    plt.close(fig)
    os.replace(path + ".tmp.png", path)


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(prog="python3 -m layertrace.sweep", description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", action="append", required=True, metavar="PATH[:CAMERA]", help="a scene, and one of its cameras (repeatable)")
    ap.add_argument("--tracers", default="ssr,ssr-layers,hssr", help="comma list of tracers (default: %(default)s)")
    ap.add_argument("--param", action="append", default=[], metavar="NAME=v1,v2,...",
                    help="a parameter by its CLI name (hssr_tau or hssr-tau) and its values (repeatable: the grid is their product)")
    ap.add_argument("--width", type=int, default=640)
    ap.add_argument("--height", type=int, default=360)
    ap.add_argument("--effect", default="reflection")
    ap.add_argument("--repeat", type=int, default=3, help="timed passes per tracer (compare's --repeat)")
    ap.add_argument("-o", "--output", default="out/sweep", help="output folder (default: %(default)s)")
    ap.add_argument("--workers", type=int, default=0, help="LocalCluster workers (default: one per 2 cores)")
    ap.add_argument("--threads", type=int, default=0, help="threads per task (default: the cores per worker)")
    ap.add_argument("--scheduler", help="tcp://HOST:8786: use a running Dask cluster instead of a LocalCluster")
    ap.add_argument("--quiet", action="store_true", help="no progress bar")
    a = ap.parse_args(argv)
    try:
        params = dict(parse_param(p) for p in a.param)
        tracers = [t for t in a.tracers.split(",") if t]
        if not tracers:
            raise ValueError("--tracers: empty list")
        for spec in a.scene:
            path, _ = parse_scene(spec)
            if not os.path.exists(path):
                raise ValueError(f"--scene {spec}: file not found")
    except ValueError as e:
        print(f"layertrace.sweep: {e}", file=sys.stderr)
        return 2
    tasks = make_tasks(a.scene, tracers, params, a.width, a.height, a.effect, {"repeat": a.repeat})

    from dask.distributed import Client, LocalCluster

    cluster = None
    threads = a.threads
    if a.scheduler:
        client = Client(a.scheduler)
    else:
        cores = os.cpu_count() or 1
        workers = a.workers or max(1, cores // 2)
        threads = threads or max(1, cores // workers)
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None)
        client = Client(cluster)
    try:
        paths = run_sweep(tasks, a.output, client, threads=threads, progress=not a.quiet)
        table = gather(paths, a.output)
    except ValueError as e:
        print(f"layertrace.sweep: {e}", file=sys.stderr)
        return 2
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    if not a.quiet:
        print(f"sweep: {len(table)} rows in {os.path.join(a.output, 'results.csv')} and {os.path.join(a.output, 'results.png')}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
