#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The validation table as a picture (docs/validation.md): per clip, the mean vertex error of the
talk's method, the binding baseline and the defaults with one reference clip (a) and with two
more takes (b), against the clip's sim-to-sim spread (the dashes: 1x and 2x the spread, the
physical limit and issue 30's bar). Reads run_validation.py's table.json of an (a) and a (b) run.

Usage: scripts/validation/plot_table.py A/table.json B/table.json -o docs/images/validation.png
"""
import argparse
import json

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402  (after choosing the backend)


def millimetres(value):
    """A table's error (mm since 2026-11-24; metres in older runs)."""
    return value * 1000.0 if value < 1.0 else value


def rows(path):
    return {r["clip"].split()[0]: r for r in json.load(open(path))}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("a", help="table.json of the run with one reference clip")
    parser.add_argument("b", help="table.json of the run with two more takes")
    parser.add_argument("-o", "--out", required=True, help="PNG to write")
    args = parser.parse_args()
    a, b = rows(args.a), rows(args.b)
    characters = [("pants", "Trousers"), ("sleeve", "Sleeve")]
    figure, axes = plt.subplots(2, 1, figsize=(12, 8.5), constrained_layout=True)
    series = [("talk (2008)", "#bbbbbb", lambda r, _: r["talk"]["mean"]),
              ("binding", "#888888", lambda r, _: r["bind"]["mean"]),
              ("defaults, 1 reference clip (a)", "#6baed6", lambda r, _: r["defaults"]["mean"]),
              ("defaults, 3 reference clips (b)", "#08519c",
               lambda _, rb: rb["defaults"]["mean"])]
    for axis, (scene, title) in zip(axes, characters):
        clips = [c for c in a if a[c]["scene"] == scene and c in b]
        width = 0.8 / len(series)
        for s, (label, colour, value) in enumerate(series):
            heights = [millimetres(value(a[c], b[c])) for c in clips]
            axis.bar([i + (s - 1.5) * width for i in range(len(clips))], heights, width,
                     label=label, color=colour)
        for i, c in enumerate(clips):
            spread = a[c].get("spread")
            if spread:
                for factor, style in ((1, "-"), (2, "--")):
                    axis.hlines(millimetres(spread) * factor, i - 0.42, i + 0.42, colors="#d62728",
                                linestyles=style, linewidth=1.5,
                                label=(f"{factor} x sim-to-sim spread" if i == 0 else None))
        axis.set_xticks(range(len(clips)))
        axis.set_xticklabels([c.replace(scene + "_", "").replace("test_public", "public test")
                              for c in clips])
        axis.set_ylabel("mean vertex error (mm)")
        axis.set_title(f"{title}: error per validation clip (lower is better; the bars stop at "
                       "45 mm)")
        axis.set_ylim(0, 45)
        axis.grid(axis="y", alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    figure.legend(handles, labels, loc="outside lower center", ncol=6, fontsize=9)
    figure.savefig(args.out, dpi=90)
    print(f"plot_table: wrote {args.out}")


if __name__ == "__main__":
    main()
