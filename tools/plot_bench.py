#!/usr/bin/env python3
"""Plots one `layertrace bench` result (NAME.json) to a PNG. Usage: plot_bench.py IN.json OUT.png"""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    data = json.load(open(sys.argv[1]))
    rows, exp = data["rows"], data["experiment"]
    fig, ax = plt.subplots(figsize=(7, 4.2))
    # The title names what the experiment sweeps, not the run's default of it.
    swept = {"stride": "SSR stride 1-8 vs HSSR", "layers": "construction time vs layers k", "memory": "memory at 720p and 1080p",
             "tau": "HSSR vs tau", "resolution": "cost vs resolution", "threads": "cost vs threads",
             "capture": "capture vs Embree all-hit, by threads", "gamma": "quadtree merge thresholds",
             "ldc": "layered depth cube: resolution x block"}
    fixed = f"{data['width']}x{data['height']}" if exp in ("layers", "threads", "stride", "tau", "capture", "gamma", "ldc") else f"k={data['layers']}"
    title = f"{exp}: {swept.get(exp, exp)} — {data['scene']} ({fixed})"
    if exp == "stride":
        ssr = [r for r in rows if r["tracer"] == "ssr-layers"]
        hssr = [r for r in rows if r["tracer"] == "hssr"][0]
        ax.plot([r["stride"] for r in ssr], [r["trace_ms"] for r in ssr], "o-", label="ssr-layers trace ms")
        ax.axhline(hssr["trace_ms"], color="C1", label="hssr trace ms")
        ax.set_xlabel("SSR stride")
        ax.set_ylabel("trace time [ms]")
        ax2 = ax.twinx()
        ax2.plot([r["stride"] for r in ssr], [100 * r["false_miss"] for r in ssr], "s--", color="C2", label="ssr-layers false miss %")
        ax2.axhline(100 * hssr["false_miss"], color="C3", ls="--", label="hssr false miss %")
        ax2.set_ylabel("false misses [% of rays]")
        ax2.legend(loc="upper center")
    elif exp == "layers":
        ks = [r["k"] for r in rows]
        ax.stackplot(ks, [r["raster_ms"] for r in rows], [r["sort_ms"] for r in rows], [r["hierarchy_ms"] for r in rows],
                     labels=["raster (all fragments)", "sort + truncate", "hierarchy"])
        ax.set_xlabel("layers k")
        ax.set_ylabel("time [ms]")
    elif exp == "memory":
        names = [r["resolution"] for r in rows]
        mib = lambda k: [r[k] / 2**20 for r in rows]  # noqa: E731
        b1, b2, b3 = mib("lists_bytes"), mib("arrays_bytes"), mib("hierarchy_bytes")
        ax.bar(names, b1, label="lists")
        ax.bar(names, b2, bottom=b1, label="arrays")
        ax.bar(names, b3, bottom=[a + b for a, b in zip(b1, b2)], label="hierarchy")
        ax.set_ylabel("memory [MiB]")
    elif exp == "tau":
        taus = [r["tau"] for r in rows]
        ax.semilogx(taus, [r["hierarchy_ms"] for r in rows], "o-", color="C3", label="hierarchy build ms")
        ax.semilogx(taus, [r["trace_ms"] for r in rows], "o-", color="C0", label="trace ms")
        ax.set_xlabel("tau [pixel footprints]")
        ax.set_ylabel("time [ms]")
    elif exp == "resolution":
        px = [r["pixels"] / 1e6 for r in rows]
        for key, lab in [("raster_ms", "raster"), ("sort_ms", "sort"), ("hierarchy_ms", "hierarchy"),
                         ("trace_hssr_ms", "trace hssr"), ("trace_ssr_layers_ms", "trace ssr-layers")]:
            ax.plot(px, [r[key] for r in rows], "o-", label=lab)
        ax.set_xlabel("megapixels")
        ax.set_ylabel("time [ms]")
    elif exp == "threads":
        th = [r["threads"] for r in rows]
        for key, lab in [("raster_ms", "raster"), ("sort_ms", "sort"), ("hierarchy_ms", "hierarchy"), ("trace_hssr_ms", "trace hssr")]:
            ax.plot(th, [r[key] for r in rows], "o-", label=lab)
        ax.set_xlabel("threads")
        ax.set_ylabel("time [ms]")
    elif exp == "capture":
        for i, pipe in enumerate(("tiles", "tiles+lists", "reference")):
            sel = [r for r in rows if r.get("pipeline", "reference") == pipe]
            if not sel:
                continue
            th = [r["threads"] for r in sel]
            ax.plot(th, [r["capture_ms"] for r in sel], "o-", color=f"C{i}", label=f"capture ({pipe}: raster + sort)")
            ax.plot(th, [r["pyramid_ms"] for r in sel], "s:", color=f"C{i}", label=f"pyramid ({pipe})")
        emb = [r for r in rows if r.get("pipeline", "reference") == "tiles"] or rows
        ax.plot([r["threads"] for r in emb], [r["embree_allhit_ms"] for r in emb], "^--", color="C3", label="Embree all-hit capture")
        ax.set_xlabel("threads")
        ax.set_ylabel("time [ms]")
    elif exp == "gamma":
        sweep = [r for r in rows if r["gamma_dist"] > 0]
        for i, norm in enumerate(sorted({r["gamma_norm"] for r in sweep})):
            sel = [r for r in sweep if r["gamma_norm"] == norm]
            ax.semilogx([r["gamma_dist"] for r in sel], [r["trace_ms"] for r in sel], "o-", color=f"C{i}",
                        label=f"trace ms, gamma_norm={norm:g}")
        ax.axhline([r for r in rows if r["gamma_dist"] == 0][0]["trace_ms"], color="k", ls=":", label="no merging")
        ax.set_xlabel("gamma_dist (relative depth)")
        ax.set_ylabel("trace time [ms]")
        ax2 = ax.twinx()
        for i, norm in enumerate(sorted({r["gamma_norm"] for r in sweep})):
            sel = [r for r in sweep if r["gamma_norm"] == norm]
            ax2.semilogx([r["gamma_dist"] for r in sel], [100 * r["changed_vs_unmerged"] for r in sel], "s--", color=f"C{i}")
        ax2.set_ylabel("answers changed vs no merging [% of rays] (dashed)")
    elif exp == "ldc":
        label = lambda r: r["tracer"] if r["tracer"] != "ldc" else f"{r['resolution']}/b{r['block']}/i{r['block_intervals']}"
        xs = range(len(rows))
        ax.bar([x - 0.2 for x in xs], [r["build_ms"] for r in rows], 0.4, label="build ms (hssr: capture + pyramid)")
        ax.bar([x + 0.2 for x in xs], [r["trace_ms"] for r in rows], 0.4, label="trace ms")
        ax.set_yscale("log")
        ax.set_xticks(list(xs), [label(r) for r in rows], rotation=30, fontsize=7)
        ax.set_ylabel("time [ms] (log)")
        ax2 = ax.twinx()
        ax2.plot(list(xs), [100 * (r["correct_hit"] + r["correct_miss"]) for r in rows], "ks--", label="correct %")
        ax2.set_ylabel("correct hit + correct miss [% of rays] (dashed)")
        ax2.set_ylim(0, 100)
    elif exp == "simd":
        xs = range(len(rows))
        stages = [("capture_ms", "capture"), ("pyramid_ms", "pyramid"), ("hssr_trace_ms", "HSSR trace"), ("grid_trace_ms", "grid traversal")]
        for i, (key, lab) in enumerate(stages):
            ax.bar([x + (i - 1.5) * 0.2 for x in xs], [r[key] for r in rows], 0.2, label=lab)
        ax.plot(list(xs), [r["embree_trace_ms"] for r in rows], "k^--", label="plain Embree, same rays")
        ax.set_xticks(list(xs), [f"{r['target']} ({r['lanes']} lanes)" for r in rows])
        ax.set_ylabel("time [ms]")
        title = f"vector targets: {data['scene']} ({data['width']}x{data['height']})"
    elif exp == "warp":
        for i, k in enumerate(sorted({r["k"] for r in rows})):
            for j, tracer in enumerate(["ssr", "hssr", "quadtree"]):
                sel = [r for r in rows if r["k"] == k and r["tracer"] == tracer]
                ax.plot([100 * r["offset"] for r in sel], [100 * r["disocclusion_fraction"] for r in sel], ["o-", "s--", "^:"][j],
                        color=f"C{i}", label=f"{tracer}, k={k}")
        ax.set_xlabel("second camera offset [% of the eye-target distance]")
        ax.set_ylabel("disocclusion holes [% of pixels inside the first view]")
        title = f"warp: holes vs second-camera offset and k — {data['scene']} ({data['width']}x{data['height']})"
    elif exp == "frame":
        idx = [r["frame"] for r in rows]
        ax.plot(idx, [r["wall_ms"] for r in rows], "o-", label="wall ms (host)")
        if any(r["gpu_ms"] > 0 for r in rows):
            soft = data.get("gpu", {}).get("software", False)
            ax.plot(idx, [r["gpu_ms"] for r in rows], "s--", label="GPU timer ms" + (" (llvmpipe: CPU time)" if soft else ""))
        ax.set_xlabel("frame (orbit of the camera)")
        ax.set_ylabel("time [ms]")
        title = f"frame: {data['device']} {data.get('tracer', '')} {data['effect']} — {data['scene']} ({data['width']}x{data['height']}, k={data['layers']})"
    ax.set_title(title, fontsize=10)
    ax.legend(loc="upper left", fontsize=8)
    fig.text(0.01, 0.01, f"{data['machine']} · {data['build_type']} · {data['date']} · median of {data['repeat']}", fontsize=6)
    fig.tight_layout()
    fig.savefig(sys.argv[2], dpi=110)


if __name__ == "__main__":
    main()
