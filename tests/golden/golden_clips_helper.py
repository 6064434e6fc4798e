#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The Python half of scripts/golden_clips.sh (hashing, caching, comparing one bake).

  golden_clips_helper.py record CACHE.json --binary B --binary-sha S --clip C --mode M
      --device D --flags "..." --frames 1-140 --pattern DIR/clip.####.exr --report R.json
      --seconds N
  golden_clips_helper.py cached CACHE.json BINARY_SHA      (exit 0 when usable for that binary)
  golden_clips_helper.py compare OLD.json NEW.json --label "pants default cpu" [--old-only]
"""

import argparse
import datetime
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import golden_bakes  # noqa: E402
import golden_pixels  # noqa: E402

FORMAT = "drivenshape-golden-clip"


def record(args):
    frames = golden_pixels.parse_frames(args.frames)
    report = golden_bakes.load_json(args.report)
    summary, records, info = golden_bakes.strip_report(report)
    exr = {str(f): golden_pixels.exr_hashes(golden_pixels.expand_pattern(args.pattern, f))
           for f in frames}
    document = {
        "format": FORMAT, "clip": args.clip, "mode": args.mode, "device": args.device,
        "flags": args.flags, "frames": args.frames,
        "binary": {"path": os.path.abspath(args.binary), "sha256": args.binary_sha},
        "recorded": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
        "seconds": args.seconds, "info": info, "summary": summary, "records": records,
        "exr": exr,
    }
    golden_bakes.dump(document, args.cache, compact_depth=2)
    return 0


def cached(args):
    try:
        document = golden_bakes.load_json(args.cache)
    except (OSError, ValueError):
        return 1
    if document.get("format") != FORMAT:
        return 1
    if document["binary"]["sha256"] != args.binary_sha:
        print(f"  {args.cache} was made by another binary ({document['binary']['path']}, "
              f"sha256 {document['binary']['sha256'][:12]}...): baking again")
        return 1
    return 0


def compare(args):
    old = golden_bakes.load_json(args.old) if os.path.exists(args.old) else None
    new = golden_bakes.load_json(args.new) if os.path.exists(args.new) and not args.old_only \
        else None
    if old is None:
        print(f"{args.label}: no OLD hashes ({args.old})")
        return 1
    total = len(old["exr"])
    if args.old_only:
        print(f"{args.label}: OLD recorded, {total} frames ({old['frames']}), database "
              f"{old['summary']['database']['content_hash']}, baked in {old['seconds']} s on "
              f"{old['info']['device']} -> {args.old}")
        return 0
    if new is None:
        print(f"{args.label}: no NEW hashes ({args.new})")
        return 1
    pixels = same_bytes = same_records = 0
    bad_pixels, bad_records = [], []
    new_records = {r["frame"]: r for r in new["records"]}
    for record_ in old["records"]:
        frame = str(record_["frame"])
        theirs = new["exr"].get(frame)
        if theirs and theirs["pixels"] == old["exr"][frame]["pixels"]:
            pixels += 1
        else:
            bad_pixels.append(frame)
        if theirs and theirs["bytes"] == old["exr"][frame]["bytes"]:
            same_bytes += 1
        if golden_bakes.same_value(record_, new_records.get(record_["frame"])):
            same_records += 1
        else:
            bad_records.append(frame)
    line = (f"{args.label}: {pixels}/{total} frames pixel-identical, {same_bytes}/{total} "
            f"byte-identical, {same_records}/{total} report records identical")
    details = []
    if bad_pixels:
        details.append(f"pixels differ at frames {','.join(bad_pixels[:10])}"
                       f"{'...' if len(bad_pixels) > 10 else ''}")
    if bad_records:
        diffs = []
        frame = int(bad_records[0])
        golden_bakes.describe_difference(
            next(r for r in old["records"] if r["frame"] == frame), new_records.get(frame),
            f"frame {frame}", diffs, limit=3)
        details.append("records differ, e.g. " + "; ".join(diffs))
    diffs = []
    golden_bakes.describe_difference(old["summary"], new["summary"], "report", diffs, limit=3)
    if diffs:
        details.append("; ".join(diffs))
    print(line + ("" if not details else "  [" + " | ".join(details) + "]"))
    return 0 if pixels == total and same_records == total and not diffs else 1


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    p = sub.add_parser("record")
    p.add_argument("cache")
    for name in ("binary", "binary-sha", "clip", "mode", "device", "flags", "frames", "pattern",
                 "report"):
        p.add_argument("--" + name, required=True)
    p.add_argument("--seconds", type=float, required=True)
    p = sub.add_parser("cached")
    p.add_argument("cache")
    p.add_argument("binary_sha")
    p = sub.add_parser("compare")
    p.add_argument("old")
    p.add_argument("new")
    p.add_argument("--label", required=True)
    p.add_argument("--old-only", action="store_true")
    args = parser.parse_args()
    return {"record": record, "cached": cached, "compare": compare}[args.command](args)


if __name__ == "__main__":
    sys.exit(main())
