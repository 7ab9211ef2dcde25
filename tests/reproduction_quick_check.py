"""Compares the counted values of a `layertrace reproduce --quick` run with the committed
docs/reproduction/quick.json: every number and label that counts something (iterations, cells,
bytes, shares of rays, table rows), not times (keys ending in _ms), not the claims' outcomes
(the run itself checks those), not Embree's own memory (it depends on the CPU's vector width),
and not the date, commit, machine, command, device or GPU. Prints one line and exits 1 on the
first difference. Counts and their ratios must agree to 1e-9; the shares of rays graded against
Embree (correct hits, misses, errors, holes, agreement) to 1e-4, since Embree, their oracle, may
answer a handful of rays differently with another vector width.

usage: reproduction_quick_check.py RUN.json COMMITTED.json
"""
import json
import math
import sys

METADATA = {"date", "commit", "machine", "command", "device", "gpu_renderer"}
REGENERATE = ("layertrace reproduce --quick --device gpu -o out/quick && "
              "cp out/quick/reproduction/reproduction.json docs/reproduction/quick.json")


def graded(key):
    return key != "hits" and any(word in key for word in ("hit", "miss", "errors", "holes", "agreement"))


def counted(key):
    return not (key.endswith("_ms") or key in ("holds", "expected") or "embree" in key)


def differences(run, committed, path):
    """Yields (path, run's value, committed value) where they differ."""
    if isinstance(committed, dict) and isinstance(run, dict):
        for key in sorted(set(run) | set(committed)):
            if (not path and key in METADATA) or not counted(key):
                continue
            yield from differences(run.get(key), committed.get(key), path + [key])
    elif isinstance(committed, list) and isinstance(run, list):
        if len(run) != len(committed):
            yield path + ["length"], len(run), len(committed)
            return
        for i, (a, b) in enumerate(zip(run, committed)):
            yield from differences(a, b, path + [str(i)])
    elif isinstance(committed, float) or isinstance(run, float):
        numbers = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (run, committed))
        tolerance = 1e-4 if path and graded(path[-1]) else 0.0
        if not numbers or not math.isclose(run, committed, rel_tol=1e-9, abs_tol=max(tolerance, 1e-12)):
            yield path, run, committed
    elif run != committed:
        yield path, run, committed


def main():
    run = json.load(open(sys.argv[1]))
    committed = json.load(open(sys.argv[2]))
    found = list(differences(run, committed, []))
    if found:
        where, mine, theirs = found[0]
        print(f"reproduce --quick: {len(found)} counted values differ from docs/reproduction/quick.json (first: "
              f"{'/'.join(where)} is {mine!r}, committed {theirs!r}); if the change is intended, regenerate it: {REGENERATE}")
        return 1
    print("reproduce --quick: every counted value as in docs/reproduction/quick.json")
    return 0


if __name__ == "__main__":
    sys.exit(main())
