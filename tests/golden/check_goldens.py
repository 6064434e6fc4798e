#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""CTest golden_sample: bakes the sleeve sample with the built `drivenshape` in every golden
configuration (tests/golden/golden_bakes.py) on the host path and the OpenCL CPU device, and
compares with the recorded goldens (tests/data/golden/f302ac6.json), exactly:

  * every point-cache EXR (and position map) per frame: the sha256 of the whole file and of
    its decoded pixels equal (the file bytes include the header's dsSettingsHash, whose layout
    the bake keeps: a resume compares it);
  * the bake report: per-frame records (weights, residuals, iterations, active sets, alignment,
    inside_* counts, resolved, binding switches, max jump; not 'output') and the summary
    (baked, skipped, database, settings; paths by file name), values and types equal.

  * the report's settings_hash.

A binary of another version than the recording's writes its version string into every file
(dsToolVersion) and into the settings hash: its files are then compared byte for byte as if
stamped with the recorded version and settings hash (golden_pixels.restamped_sha256), and the
settings hash is only reported (tests/pipeline/test_settings_hash pins its layout).

Configurations whose default output changed on purpose after the recording bake with the flags
that restore the recorded output (golden_bakes.SINCE_RECORDING: --zip-encoder openexr for every
configuration, --posmap-channels legacy).

A missing OpenCL device fails (never skips).

  .venv/bin/python tests/golden/check_goldens.py --cli build/apps/drivenshape
      [--golden tests/data/golden/f302ac6.json] [--work DIR] [--configs default,talk]
      [--devices host] [--extra-flags "--skin-offset 0.003"] [--keep]
      [--settings-doc build/apps/drivenshape_settings_doc]

--extra-flags appends flags to every bake (to see the check fail on purpose).
"""

import argparse
import json
import os
import shlex
import shutil
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import golden_bakes  # noqa: E402

DEFAULT_GOLDEN = os.path.join(golden_bakes.GOLDEN_DATA, "f302ac6.json")


def table_defaults(settings_doc):
    """{report key: default} of the settings table (`drivenshape_settings_doc --json`)."""
    if not settings_doc:
        return {}
    table = json.loads(subprocess.run([settings_doc, "--json"], check=True, capture_output=True,
                                      text=True).stdout)
    return {row["report_key"]: row["default"] for row in table if row.get("report_key")}


def compare_bake(expected, actual, defaults=None, version_changed=False):
    """(problems, notes): lines naming config/device/frame/field for each difference.
    `defaults`: the settings table's {report key: default}; a report setting the recording
    lacks that holds its default is a setting added since, which left the bake as it was.
    version_changed: the binary is another version than the recording's, so the files are
    compared byte for byte as restamped with the recorded version and settings hash (the hash
    hashes the version string; tests/pipeline/test_settings_hash pins its layout)."""
    tag = f"{expected['config']} {expected['device']}"
    problems, notes = [], []

    summary = actual["summary"]
    recorded = expected["summary"].get("settings", {})
    added = [key for key, value in summary.get("settings", {}).items()
             if key not in recorded and key in (defaults or {}) and value == defaults[key]]
    if added:
        notes.append(f"{tag}: settings added since the goldens, at their defaults (not "
                     f"compared): {', '.join(sorted(added))}")
        summary = dict(summary, settings={k: v for k, v in summary["settings"].items()
                                          if k not in added})
    diffs = []
    golden_bakes.describe_difference(expected["summary"], summary, "report", diffs)
    problems += [f"{tag}: {d}" for d in diffs]

    want = [{k: v for k, v in r.items() if k not in golden_bakes.FRAME_MOVED}
            for r in expected["frames"]]
    got = actual["frames"]
    if [r.get("frame") for r in want] != [r.get("frame") for r in got]:
        problems.append(f"{tag}: report frames {[r.get('frame') for r in got]}, expected "
                        f"{[r.get('frame') for r in want]}")
    else:
        # Fields added to the records since the goldens were recorded have nothing to be
        # compared with: they are named in a note; every recorded field is compared.
        recorded = set().union(*(r.keys() for r in want)) if want else set()
        added = sorted(set().union(*(r.keys() for r in got)) - recorded) if got else []
        if added:
            notes.append(f"{tag}: record fields added since the goldens (not compared): "
                         f"{', '.join(added)}")
            got = [{k: v for k, v in r.items() if k in recorded} for r in got]
        bad_frames = 0
        for w, g in zip(want, got):
            if golden_bakes.same_value(w, g):
                continue
            bad_frames += 1
            if bad_frames <= 5:
                diffs = []
                golden_bakes.describe_difference(w, g, "record", diffs, limit=6)
                problems += [f"{tag} frame {w['frame']}: {d}" for d in diffs]
        if bad_frames > 5:
            problems.append(f"{tag}: ... report records differ on {bad_frames} of {len(want)} "
                            "frames in all")

    report_problems = len(problems)
    counts = {}
    for kind in ("exr", "posmap"):
        if kind not in expected and kind not in actual:
            continue
        if kind not in actual or kind not in expected:
            problems.append(f"{tag}: {kind} files {'missing' if kind in expected else 'extra'}")
            continue
        pixels = same_bytes = same_header = 0
        bad = []
        for frame, hashes in expected[kind].items():
            have = actual[kind].get(frame)
            if have is None:
                bad.append(f"{frame} (missing)")
                continue
            if have["pixels"] == hashes["pixels"]:
                pixels += 1
            else:
                bad.append(frame)
            if (have["restamped"] if version_changed else have["bytes"]) == hashes["bytes"]:
                same_bytes += 1
            elif have["pixels"] == hashes["pixels"]:
                bad.append(f"{frame} (same pixels, other file bytes)")
            same_header += have["header"] == hashes["header"]
        total = len(expected[kind])
        label = "point caches" if kind == "exr" else "position maps"
        if bad:
            problems.append(f"{tag}: {label}: pixels or file bytes differ on {len(bad)} of {total} "
                            f"frames: {', '.join(bad[:12])}{' ...' if len(bad) > 12 else ''}")
        counts[kind] = (pixels, same_bytes, same_header, total)

    if expected["info"]["device"] != actual["info"]["device"]:
        notes.append(f"{tag}: device '{actual['info']['device']}' (recorded on "
                     f"'{expected['info']['device']}')")
    if version_changed:
        notes.append(f"{tag}: settings hash {actual['info']['settings_hash']} (recorded "
                     f"{expected['info']['settings_hash']} by another version; not compared)")
    elif expected["info"]["settings_hash"] != actual["info"]["settings_hash"]:
        problems.append(f"{tag}: settings hash {actual['info']['settings_hash']} (recorded "
                        f"{expected['info']['settings_hash']})")
    return problems, notes, counts, report_problems


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--cli", required=True, help="the drivenshape binary under test")
    parser.add_argument("--golden", default=DEFAULT_GOLDEN, help="recorded goldens (JSON)")
    parser.add_argument("--work", help="scratch folder (default: a temporary one)")
    parser.add_argument("--configs", help="comma-separated subset of the configurations")
    parser.add_argument("--devices", help="comma-separated subset of host,cpu")
    parser.add_argument("--extra-flags", default="", help="flags appended to every bake")
    parser.add_argument("--keep", action="store_true", help="keep the bakes and the work folder")
    parser.add_argument("--settings-doc",
                        help="drivenshape_settings_doc, whose --json gives the settings table's "
                             "defaults (report settings added since the recording)")
    args = parser.parse_args()

    golden = golden_bakes.load_json(args.golden)
    if golden.get("format") != golden_bakes.FORMAT or \
            golden.get("format_version") != golden_bakes.FORMAT_VERSION:
        sys.exit(f"check_goldens: {args.golden} is not a version {golden_bakes.FORMAT_VERSION} "
                 f"{golden_bakes.FORMAT} file")
    print(f"goldens: {args.golden} (commit {golden['commit']}, recorded {golden['recorded']})")

    failures = []
    inputs = golden_bakes.input_hashes()
    for name, digest in golden["inputs"].items():
        if inputs.get(name) != digest:
            failures.append(f"input tests/data/{name} changed since the goldens were recorded")
    table = {name: flags for name, flags, _ in golden_bakes.CONFIGS}
    for name, entry in golden["configs"].items():
        if table.get(name) != entry["flags"]:
            failures.append(f"configuration {name}: flags {table.get(name)} in golden_bakes.py, "
                            f"{entry['flags']} when recorded")
    for name in table:
        if name not in golden["configs"]:
            print(f"note: configuration {name} is not in the goldens (not checked; re-record)")
    if failures:
        print("\n".join("FAIL " + f for f in failures))
        print("the goldens no longer describe these bakes: re-record them from the old commit")
        return 1

    configs = args.configs.split(",") if args.configs else list(golden["configs"])
    devices = args.devices.split(",") if args.devices else golden["bake"]["devices"]
    extra = shlex.split(args.extra_flags)
    if extra:
        print(f"extra flags on every bake: {extra}")
        golden_bakes.CONFIGS = [(n, f + extra, w) for n, f, w in golden_bakes.CONFIGS]

    for name in configs:
        if golden_bakes.SINCE_RECORDING.get(name):
            print(f"configuration {name}: + {' '.join(golden_bakes.SINCE_RECORDING[name])} "
                  "(a default changed since the recording; golden_bakes.SINCE_RECORDING)")

    expected = {(b["config"], b["device"]): b for b in golden["bakes"]}
    version = subprocess.run([args.cli, "--version"], capture_output=True, text=True,
                             check=True).stdout.strip()
    recorded_version = golden["binary"]["version"]
    version_changed = version != recorded_version
    restamp = None
    if version_changed:
        print(f"{version}, recorded by {recorded_version}: files are compared byte for byte as "
              "if stamped with the recorded version and settings hash (dsToolVersion, "
              "dsSettingsHash)")

        def restamp(config, device):
            if (config, device) not in expected:
                return None
            return {"dsToolVersion": recorded_version.split()[-1],
                    "dsSettingsHash": expected[(config, device)]["info"]["settings_hash"]}

    work = args.work or tempfile.mkdtemp(prefix="ds-golden-check-")
    start = time.monotonic()
    try:
        baked = golden_bakes.bake_all(os.path.abspath(args.cli), work, configs, devices,
                                      keep=args.keep, log=lambda line: print("  " + line),
                                      since_recording=True, restamp=restamp)
    except RuntimeError as error:
        print(f"FAIL bake: {error}")
        print(f"(work folder kept: {work})")
        return 1
    seconds = time.monotonic() - start

    defaults = table_defaults(args.settings_doc)
    problems, notes, lines = [], [], []
    for bake in baked["bakes"]:
        key = (bake["config"], bake["device"])
        if key not in expected:
            problems.append(f"{key[0]} {key[1]}: not in the goldens")
            continue
        p, n, counts, report_problems = compare_bake(expected[key], bake, defaults,
                                                     version_changed)
        problems += p
        notes += n
        parts = []
        for kind, (pixels, same_bytes, same_header, total) in counts.items():
            label = "" if kind == "exr" else "posmap "
            parts.append(f"{label}{pixels}/{total} pixel-identical, {same_bytes}/{total} "
                         f"byte-identical")
        verdict = "ok  " if not p else "FAIL"
        report = "report DIFFERS" if report_problems else "report identical"
        lines.append(f"{verdict} {key[0]} {key[1]}: {'; '.join(parts)}; {report} "
                     f"({bake['seconds']:.1f} s)")

    print("\n".join(lines))
    for note in notes:
        print("note: " + note)
    for problem in problems:
        print("FAIL " + problem)
    print(f"{len(baked['bakes'])} bakes in {seconds:.1f} s; "
          f"{'all match the goldens' if not problems else f'{len(problems)} differences'}")
    if problems or args.keep:
        print(f"(work folder kept: {work}; --keep keeps the bakes too)")
    elif not args.work:
        shutil.rmtree(work, ignore_errors=True)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
