#!/usr/bin/env python3
"""The table of scripts/rig_benchmark.sh: per rig, over the clips it ran, rollout PMD_a of the learned output as a
ratio to rigid skinning's (mean and worst clip), mean dynamics amplitude, tearing, apparel ELS and the share of the
apparel inside the body ("in"), then the mean
over the rigs. Usage: scripts/rig_benchmark.py OUT VARIANT [VARIANT ...] (one column per variant)."""
import json
import os
import sys


def row(path, method):
    with open(path) as f:
        rows = json.load(f)["rows"]
    for r in rows:
        if r["method"] == method and r["protocol"] in ("rollout", "file"):
            return r
    raise SystemExit(f"{path}: rows: expected a rollout (or file) row of method {method}")


def rig_figures(out, variant, rig):
    figures = []
    folder = os.path.join(out, variant, rig)
    for clip in sorted(os.listdir(folder)):
        scored = os.path.join(folder, clip, "metrics.json")
        if not os.path.isfile(scored):
            continue
        p = row(scored, "predictions")
        s = row(os.path.join(out, "skinning", rig, clip, "metrics.json"), "skinning_baseline")
        figures.append((p["pmd_a_cm"] / s["pmd_a_cm"], p["dynamics_amplitude"], p["falling_apart"]["tearing"],
                        p["falling_apart"]["apparel_els"], p["penetration_share"]))
    return figures


def main():
    if len(sys.argv) < 3:
        raise SystemExit(__doc__)
    out, variants = sys.argv[1], sys.argv[2:]
    rigs = sorted({r for v in variants for r in os.listdir(os.path.join(out, v))
                   if os.path.isdir(os.path.join(out, v, r))})
    print("| rig | " + " | ".join(variants) + " |")
    print("|---|" + "---:|" * len(variants))
    means = {v: [] for v in variants}
    for rig in rigs:
        cells = []
        for v in variants:
            f = rig_figures(out, v, rig) if os.path.isdir(os.path.join(out, v, rig)) else []
            if not f:
                cells.append("-")
                continue
            n = len(f)
            ratio = sum(x[0] for x in f) / n
            worst = max(x[0] for x in f)
            amp = sum(x[1] for x in f if x[1] is not None) / n
            tear = sum(x[2] for x in f) / n
            els = sum(x[3] for x in f) / n
            inside = sum(x[4] for x in f) / n
            means[v].append((ratio, worst, amp, tear, els, inside))
            cells.append(f"{ratio:.3f} / {worst:.3f}, a {amp:.2f}, {100 * tear:.2f} %, {els:.3f}, in {100 * inside:.2f} % ({n})")
        print(f"| {rig} | " + " | ".join(cells) + " |")
    cells = []
    for v in variants:
        m = means[v]
        if not m:
            cells.append("-")
            continue
        n = len(m)
        cells.append(f"{sum(x[0] for x in m) / n:.3f} / {max(x[1] for x in m):.3f}, a {sum(x[2] for x in m) / n:.2f}, "
                     f"{100 * sum(x[3] for x in m) / n:.2f} %, {sum(x[4] for x in m) / n:.3f}, "
                     f"in {100 * sum(x[5] for x in m) / n:.2f} %")
    print("| mean of the rigs (worst clip) | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
