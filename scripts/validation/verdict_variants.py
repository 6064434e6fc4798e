#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""How the coverage verdict's error bound would hold with other calibrations (issue 30), from a
validation run (run_validation.py's table.json and the `db build --model-json` of each
character, both in its --out folder): per character, level and tolerance, the share of frames
called enough whose true mean error is within the tolerance, and how many are called enough.

  ratio   the bound is the prediction times the conformal quantile of error / prediction
  margin  the bound is the prediction plus the conformal quantile of error - prediction (what
          db build does)

Both are calibrated here the way db build calibrates the margin: on the reference frames' held-out
errors and predictions (the cross-validation's with one reference clip, each frame's clip left
out with several), the ceil((n + 1) level)-th smallest score.

Usage: scripts/validation/verdict_variants.py OUT_DIR [--levels 0.8 0.9 0.95]
"""
import argparse
import json
import math
import os

FRACTIONS = (0.01, 0.015, 0.02, 0.03)


def conformal(scores, level):
    ordered = sorted(scores)
    rank = min(len(ordered), max(1, math.ceil((len(ordered) + 1) * level)))
    return ordered[rank - 1]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("out")
    ap.add_argument("--levels", nargs="+", type=float, default=[0.8, 0.9, 0.95])
    a = ap.parse_args()
    rows = json.load(open(os.path.join(a.out, "table.json")))
    print("| character | calibration | level | " + " | ".join(
        f"{f:.1%}: enough, truly within" for f in FRACTIONS) + " |")
    print("|---|---|---|" + "---|" * len(FRACTIONS))
    for scene in ("pants", "sleeve"):
        model = json.load(open(os.path.join(a.out, scene + ".model.json")))
        # Held out as db build holds them: each frame's whole clip left out when there are
        # several clips, else the 5-fold cross-validation.
        left_out = all("left_out_error" in f for f in model["frames"])
        errors = [f["left_out_error" if left_out else "error"] for f in model["frames"]]
        line = model["error_line"]
        predicted = [line["bias"] + line["scale"] * f["left_out_sigma" if left_out else "sigma"]
                     for f in model["frames"]]
        sel = [r for r in rows if r["scene"] == scene and "pred" in r]
        frames = [(p[0], p[1]) for r in sel for p in r["pred"]]  # (predicted, true)
        diagonal = sel[0]["defaults"]["coverage"]["tolerance"] / 0.02
        for kind in ("ratio", "margin"):
            for level in a.levels:
                if kind == "ratio":
                    s = max(1.0, conformal([e / max(p, 1e-12) for e, p in zip(errors, predicted)],
                                           level))
                    bound = [p * s for p, _ in frames]
                    what = f"x {s:.2f}"
                else:
                    m = max(0.0, conformal([e - p for e, p in zip(errors, predicted)], level))
                    bound = [p + m for p, _ in frames]
                    what = f"+ {m * 1e3:.1f} mm"
                cells = []
                for fraction in FRACTIONS:
                    tolerance = fraction * diagonal
                    enough = [t for b, (_, t) in zip(bound, frames) if b <= tolerance]
                    within = sum(1 for t in enough if t <= tolerance)
                    cells.append(f"{len(enough) / len(frames):.0%}, " + (
                        f"{within / len(enough):.0%}" if enough else "-"))
                print(f"| {scene} | {kind} {what} | {level:.2f} | " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main()
