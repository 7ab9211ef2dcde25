#!/usr/bin/env python3
"""Plots of `layertrace reproduce`: reads its JSON, writes one PNG per figure beside OUT, then OUT.

usage: plot_reproduction.py REPRODUCTION.json OUT
"""
import json
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def rows(data, table):
    return data["tables"].get(table, {}).get("rows", [])


def views(rs):
    seen = []
    for r in rs:
        if r["view"] not in seen:
            seen.append(r["view"])
    return seen


def iterations(data, folder):
    rs = rows(data, "hssr_iterations")
    if not rs:
        return
    fig, ax = plt.subplots(figsize=(8, 4))
    labels = [f'{r["view"]}\n{r["preset"]}' for r in rs]
    keys = [("hssr", "HSSR"), ("ssr_stride1", "SSR stride 1"), ("ssr_stride4", "SSR stride 4"), ("ssr_stride8", "SSR stride 8")]
    width = 0.8 / len(keys)
    for i, (key, name) in enumerate(keys):
        ax.bar([x + i * width for x in range(len(rs))], [r[key] for r in rs], width, label=name)
    ax.set_xticks([x + 0.4 - width / 2 for x in range(len(rs))])
    ax.set_xticklabels(labels, fontsize=7)
    ax.set_ylabel("iterations per ray")
    ax.set_title("One-bounce reflections: HSSR against SSR (Hofmann et al. 2017, Fig. 10-12)")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(os.path.join(folder, "hssr_iterations.png"), dpi=110)


def tau(data, folder):
    rs = rows(data, "hssr_tau")
    if not rs:
        return
    fig, ax = plt.subplots(figsize=(7, 4))
    for v in views(rs):
        for preset in ("paper", "tuned"):
            pts = [r for r in rs if r["view"] == v and r["preset"] == preset]
            ax.plot([r["tau"] for r in pts], [r["iterations"] for r in pts], marker="o", label=f"{v} ({preset})")
    ax.set_xscale("log")
    ax.set_xlabel("tau (pixel footprints)")
    ax.set_ylabel("iterations per ray")
    ax.axvspan(15, 35, color="0.9")
    ax.set_title("The merge threshold (Hofmann et al. 2017, Fig. 14); grey: the paper's sweet spot")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(folder, "hssr_tau.png"), dpi=110)


def construction(data, folder):
    rs = rows(data, "hssr_construction")
    if not rs:
        return
    fig, ax = plt.subplots(figsize=(7, 4))
    for v in views(rs):
        pts = [r for r in rs if r["view"] == v]
        ax.plot([r["k"] for r in pts], [r["lists_ms"] for r in pts], marker="o", label=f"{v}: lists")
        ax.plot([r["k"] for r in pts], [r["peel_ms"] for r in pts], marker="s", linestyle="--", label=f"{v}: depth peeling")
    ax.set_xlabel("layers k")
    ax.set_ylabel("construction ms (this CPU)")
    ax.set_title("Lists against depth peeling (Hofmann et al. 2017, Fig. 8)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(folder, "hssr_construction.png"), dpi=110)


def population(data, folder):
    rs = rows(data, "hssr_population")
    if not rs:
        return
    fig, ax = plt.subplots(figsize=(7, 4))
    for v in views(rs):
        pts = [r for r in rs if r["view"] == v]
        ax.plot([r["level"] for r in pts], [r["mean"] for r in pts], marker="o", label=v)
    ax.set_xlabel("pyramid level")
    ax.set_ylabel("mean intervals per covered cell")
    ax.set_title("Level population at tau = 25 (Hofmann et al. 2017, Fig. 13)")
    ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(os.path.join(folder, "hssr_population.png"), dpi=110)


def main():
    data = json.load(open(sys.argv[1]))
    out = sys.argv[2]
    folder = os.path.dirname(out) or "."
    for plot in (iterations, tau, construction, population):
        plot(data, folder)
    open(out, "w").close()


if __name__ == "__main__":
    main()
