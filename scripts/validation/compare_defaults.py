#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""A change of the defaults judged clip by clip: the `defaults` mode of two validation runs
(run_validation.py's table.json), BEFORE and AFTER, on the clips both ran.

    scripts/validation/compare_defaults.py BEFORE/table.json AFTER/table.json

Per clip it prints AFTER's mean vertex error against BEFORE's (the ratio), the cloth inside the
body and the largest frame jump of both, and AFTER's strain against the simulation's (the
truth's, which both runs measure the same): mean |strain|, its 95th percentile and the share of
edges over 10%, each as AFTER / truth. The bars (issue 43) are judged per clip and listed in the
last column: strain mean and p95 <= STRAIN_BAR x the truth's, share over 10% <= SHARE_BAR x the
truth's, error <= ERROR_BAR x BEFORE's, inside and jump no more than BEFORE's. Exit status 0
whatever the verdicts (it reports; it does not gate), 2 on a bad argument.
"""

import argparse
import json
import sys

STRAIN_BAR = 1.5
SHARE_BAR = 2.0
ERROR_BAR = 1.03


def load(path):
    try:
        rows = json.load(open(path))
    except (OSError, ValueError) as error:
        sys.exit(f"compare_defaults: {path}: {error}")
    return {row["clip"]: row for row in rows if "defaults" in row}


def ratio(a, b):
    return a / b if b > 0 else float("inf") if a > 0 else 1.0


def judge(before, after):
    """The row's figures and the bars it misses."""
    b, a = before["defaults"], after["defaults"]
    strain, truth = a["strain"], a["truth_strain"]
    figures = {
        "error": (b["mean"], a["mean"], ratio(a["mean"], b["mean"])),
        "inside": (b["inside"], a["inside"]),
        "jump": (b["jump"], a["jump"], a["truth_jump"]),
        "mean": (strain["strain_mean"], truth["strain_mean"]),
        "p95": (strain["strain_p95"], truth["strain_p95"]),
        "share": (strain["strain_share_over_10pct"], truth["strain_share_over_10pct"]),
    }
    misses = []
    if figures["error"][2] > ERROR_BAR:
        misses.append("error")
    if a["inside"] > b["inside"]:
        misses.append("inside")
    if a["jump"] > b["jump"]:
        misses.append("jump")
    for key, bar in (("mean", STRAIN_BAR), ("p95", STRAIN_BAR), ("share", SHARE_BAR)):
        value, sim = figures[key]
        if value > bar * sim:
            misses.append(f"strain {key}")
    return figures, misses


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("before")
    ap.add_argument("after")
    args = ap.parse_args()
    before, after = load(args.before), load(args.after)
    clips = [clip for clip in after if clip in before]
    if not clips:
        sys.exit("compare_defaults: no clip has the defaults mode in both tables")
    print("| clip | error mm before / after (ratio) | inside / frame before / after | largest "
          "jump mm before / after (truth) | mean \\|strain\\| % (truth, ratio) | strain p95 % "
          "(truth, ratio) | edges > 10% % (truth, ratio) | misses |")
    print("|---|---|---|---|---|---|---|---|")
    missed = 0
    for clip in clips:
        f, misses = judge(before[clip], after[clip])
        missed += bool(misses)
        strain = [f"{v:.2f} ({t:.2f}, {ratio(v, t):.2f})"  # in % already
                  for v, t in (f["mean"], f["p95"], f["share"])]
        print(f"| {clip} | {f['error'][0]:.2f} / {f['error'][1]:.2f} ({f['error'][2]:.3f}) | "
              f"{f['inside'][0]:.2f} / {f['inside'][1]:.2f} | {f['jump'][0]:.1f} / "
              f"{f['jump'][1]:.1f} ({f['jump'][2]:.1f}) | {' | '.join(strain)} | "
              f"{', '.join(misses) or '-'} |")
    print(f"\n{len(clips) - missed} of {len(clips)} clips meet every bar (strain mean and p95 <= "
          f"{STRAIN_BAR} x the truth's, share over 10% <= {SHARE_BAR} x, error <= {ERROR_BAR} x "
          "before, inside and jump no more than before).")


if __name__ == "__main__":
    main()
