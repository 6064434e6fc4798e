#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Regenerates the bundled sample shot in tests/data/sleeve from the public sleeve clips.

The source (--source, default out/data/sleeve) is a folder with the sleeve's rest OBJs, `train`
and `test_public` clips: the public clips of scripts/validation/clips.txt, made and linked by
`scripts/validation/generate_clips.sh --link-data out/data out/clips`. The sample in the
repository was cut from clips of an earlier generator, so a new cut differs from it (and the
tests' recorded figures with it).

The sample is small on purpose (a few MB): every 5th frame of the range-of-motion `train` clip
(after the preroll) to build a database from, and the first 48 frames of motion of
`test_public` (driver to bake, driven as the simulated truth to compare with). Frames are
renumbered from 1 in the written PC2 files; the JSON beside them records which source frames
they are. Only the standard library is used, so this runs without the project's venv.
"""
import argparse
import json
import os
import struct
import shutil

HEADER = struct.Struct("<12siiffi")


def read_pc2(path):
    with open(path, "rb") as f:
        data = f.read()
    magic, version, points, start, rate, samples = HEADER.unpack_from(data, 0)
    assert magic == b"POINTCACHE2\0" and version == 1, path
    frame_bytes = points * 12
    frames = [data[HEADER.size + i * frame_bytes: HEADER.size + (i + 1) * frame_bytes]
              for i in range(samples)]
    return points, start, frames


def write_pc2(path, points, frames):
    with open(path + ".tmp", "wb") as f:
        f.write(HEADER.pack(b"POINTCACHE2\0", 1, points, 1.0, 1.0, len(frames)))
        for frame in frames:
            f.write(frame)
    os.replace(path + ".tmp", path)


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--source", default=os.path.join(here, "..", "out", "data", "sleeve"),
                        help="the sleeve folder of generate_clips.sh --link-data (default "
                        "out/data/sleeve)")
    parser.add_argument("--out", default=os.path.join(here, "..", "tests", "data", "sleeve"))
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)
    for name in ("driver_rest.obj", "driven_rest.obj"):
        shutil.copyfile(os.path.join(args.source, name), os.path.join(args.out, name))

    picks = {
        # source frames are 1-based; frame 1 (rest) plus every 5th frame of motion
        "train": [1] + list(range(21, 321, 5)),
        "test": list(range(21, 69)),
    }
    sources = {"train": "train", "test": "test_public"}
    for key, frames in picks.items():
        for part in ("driver", "driven"):
            points, start, all_frames = read_pc2(
                os.path.join(args.source, f"{sources[key]}.{part}.pc2"))
            chosen = [all_frames[int(f - start)] for f in frames]
            write_pc2(os.path.join(args.out, f"{key}.{part}.pc2"), points, chosen)
    with open(os.path.join(args.out, "sample.json"), "w") as f:
        json.dump({"scene": "sleeve",
                   "source": "the sleeve train and test_public clips of scripts/clipgen "
                             "(Blender cloth), renumbered from frame 1",
                   "train_source_frames": picks["train"],
                   "test_source_frames": picks["test"],
                   "fps": 24,
                   # The cloth's pin group (scripts/sample_scene.py builds the demo's scene).
                   "pin_vertices": json.load(open(os.path.join(args.source, "rig.json")))[
                       "driven_pin_vertices"]}, f, indent=1)


if __name__ == "__main__":
    main()
