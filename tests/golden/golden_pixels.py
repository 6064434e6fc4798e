#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Hashes of EXR files that do not depend on drivenshape's own EXR reader.

For each file:
  * pixels: sha256 of the DECODED pixel data, read with the OpenEXR Python bindings
    (scripts/requirements.txt, the project venv). Fed to the hash, in order: the data window
    (xmin ymin xmax ymax), then per channel in sorted name order the channel name, its pixel
    type (numpy dtype, little-endian), its x/y sampling and its pixels as raw C-order bytes.
    Two files with the same pixels hash the same whatever their compression, header
    attributes (dsSettingsHash, dsToolVersion, ...) or chunk layout.
  * bytes: sha256 of the whole file, byte for byte (strict; headers included).
  * header: sha256 of the header attributes except dsSettingsHash (informational: tells a
    header change apart from a pixel change when `bytes` differs).

Usage:
  golden_pixels.py FILE.exr [FILE.exr ...]
  golden_pixels.py --pattern "out/cloth.####.exr" --frames 1-48[,60,70-80x2]
  ... [--json OUT.json]      (also writes {"path": {"pixels":..., "bytes":..., "header":...}})

Prints one line per file: `<pixels sha256> <bytes sha256> <path>`. Importable:
exr_hashes(path) -> dict, expand_pattern(pattern, frame), parse_frames(text).
"""

import argparse
import hashlib
import json
import re
import struct
import sys

try:
    import numpy as np
    import OpenEXR
except ImportError as error:  # a failure, never a skip
    print(f"golden_pixels: {error}; run scripts/setup.sh to create .venv with "
          "scripts/requirements.txt (numpy, OpenEXR)", file=sys.stderr)
    sys.exit(1)

# Header attributes left out of the informational header hash: the settings hash may change
# legitimately (it names the settings, not the result).
HEADER_IGNORED = ("dsSettingsHash", "dsRecord")
# Attributes added since the recording that the file bytes are compared without: each baked
# frame's record (dsRecord, after 0.2.0), which the report's records are compared with instead.
ADDED_ATTRIBUTES = ("dsRecord",)


def without_attributes(data, names):
    """The bytes of a single-part scan-line EXR without the header attributes `names`: the
    file another version that did not write them would have written. Each attribute is
    name\\0 type\\0 int32 size, value; the header ends with a 0 byte and the line offset table
    (uint64 file offsets, the first pointing right after the table) follows, so every offset
    moves back by the bytes taken out. Other files come back as they are."""
    if data[:4] != b"\x76\x2f\x31\x01":  # not an OpenEXR file
        return data
    at, removed, out = 8, 0, bytearray(data[:8])
    while data[at] != 0:
        name_end = data.index(b"\0", at)
        type_end = data.index(b"\0", name_end + 1)
        (size,) = struct.unpack_from("<i", data, type_end + 1)
        end = type_end + 5 + size
        if data[at:name_end].decode("utf-8", "replace") in names:
            removed += end - at
        else:
            out += data[at:end]
        at = end
    table = at + 1
    (first,) = struct.unpack_from("<Q", data, table)
    count = (first - table) // 8
    out += b"\0"
    for i in range(count):
        (offset,) = struct.unpack_from("<Q", data, table + 8 * i)
        out += struct.pack("<Q", offset - removed)
    out += data[table + 8 * count:]
    return bytes(out)


def file_sha256(path):
    """sha256 of the file's bytes, without the ADDED_ATTRIBUTES."""
    with open(path, "rb") as f:
        data = f.read()
    return hashlib.sha256(without_attributes(data, ADDED_ATTRIBUTES)).hexdigest()


def _attribute_text(value):
    """A stable text for a header attribute value (numpy arrays, tuples, enums, fractions)."""
    if isinstance(value, np.ndarray):
        return f"{value.dtype.str}{list(value.shape)}:{value.tobytes().hex()}"
    if isinstance(value, (tuple, list)):
        return "[" + ",".join(_attribute_text(v) for v in value) + "]"
    if isinstance(value, float):
        return struct.pack("<d", value).hex()
    return repr(value)


def restamped_sha256(path, values):
    """sha256 of the file's bytes with each string header attribute named in `values` holding
    that value instead (same length only: the header keeps its size, the offset table its
    offsets): the bytes a file would have had if written by another version, whose version
    string and settings hash (which hashes the version) were these. An attribute the file does
    not hold (a position map has no settings hash) is left out; an attribute whose value has
    another length makes it a hash of nothing: None."""
    with open(path, "rb") as f:
        data = without_attributes(f.read(), ADDED_ATTRIBUTES)
    for name, value in values.items():
        new = value.encode("utf-8")
        key = name.encode("utf-8") + b"\0string\0" + struct.pack("<i", len(new))
        at = data.find(name.encode("utf-8") + b"\0string\0")
        if at < 0:
            continue
        at = data.find(key)
        if at < 0:
            return None
        start = at + len(key)
        data = data[:start] + new + data[start + len(new):]
    return hashlib.sha256(data).hexdigest()


def exr_hashes(path, restamp=None):
    """{"pixels": sha256 of the decoded pixels, "bytes": of the file, "header": of the header};
    with `restamp` (attribute -> value), also "restamped": restamped_sha256(path, restamp)."""
    image = OpenEXR.File(path, separate_channels=True)
    if len(image.parts) != 1:
        raise ValueError(f"{path}: {len(image.parts)} parts; expected a single-part EXR")
    header = image.header()
    (xmin, ymin), (xmax, ymax) = (tuple(int(c) for c in corner) for corner in header["dataWindow"])
    pixels = hashlib.sha256()
    pixels.update(struct.pack("<4i", xmin, ymin, xmax, ymax))
    channels = image.channels()
    for name in sorted(channels):
        channel = channels[name]
        data = np.ascontiguousarray(channel.pixels)
        data = data.astype(data.dtype.newbyteorder("<"), copy=False)
        pixels.update(name.encode("utf-8") + b"\0")
        pixels.update(data.dtype.str.encode("ascii") + b"\0")
        pixels.update(struct.pack("<2i", channel.xSampling, channel.ySampling))
        pixels.update(struct.pack("<2q", *data.shape))
        pixels.update(data.tobytes(order="C"))
    head = hashlib.sha256()
    for key in sorted(header):
        if key in HEADER_IGNORED:
            continue
        head.update(key.encode("utf-8") + b"=" + _attribute_text(header[key]).encode("utf-8") +
                    b"\n")
    out = {"pixels": pixels.hexdigest(), "bytes": file_sha256(path), "header": head.hexdigest()}
    if restamp:
        out["restamped"] = restamped_sha256(path, restamp)
    return out


_HASH_TOKEN = re.compile(r"#+")
_PRINTF_TOKEN = re.compile(r"%0?(\d*)d")
_HOUDINI_TOKEN = re.compile(r"\$F(\d*)")


def expand_pattern(pattern, frame):
    """`####`, `%04d` or `$F4` (README, Formats) replaced by the frame number."""
    def padded(width):
        return f"{frame:0{width}d}" if frame >= 0 else f"-{-frame:0{max(width - 1, 0)}d}"
    if _HASH_TOKEN.search(pattern):
        match = list(_HASH_TOKEN.finditer(pattern))[-1]
        return pattern[:match.start()] + padded(len(match.group(0))) + pattern[match.end():]
    match = _PRINTF_TOKEN.search(pattern)
    if match:
        width = int(match.group(1) or 0)
        return pattern[:match.start()] + padded(width) + pattern[match.end():]
    match = _HOUDINI_TOKEN.search(pattern)
    if match:
        width = int(match.group(1) or 0)
        return pattern[:match.start()] + padded(width) + pattern[match.end():]
    raise ValueError(f"pattern '{pattern}' has no frame token (####, %04d, $F4)")


def parse_frames(text):
    """`1-48`, `1-48x2`, `1,5,10-20` (README, Formats)."""
    frames = []
    for part in text.split(","):
        match = re.fullmatch(r"(-?\d+)(?:-(-?\d+)(?:x(\d+))?)?", part.strip())
        if not match:
            raise ValueError(f"bad frame range '{part}'")
        first = int(match.group(1))
        last = int(match.group(2)) if match.group(2) is not None else first
        step = int(match.group(3) or 1)
        frames.extend(range(first, last + 1, step))
    return frames


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("files", nargs="*", help="EXR files")
    parser.add_argument("--pattern", help="frame pattern, e.g. out/cloth.####.exr")
    parser.add_argument("--frames", help="frames for --pattern, e.g. 1-48")
    parser.add_argument("--json", help="also write the hashes to this JSON file")
    args = parser.parse_args(argv)
    paths = list(args.files)
    if args.pattern:
        if not args.frames:
            parser.error("--pattern needs --frames")
        paths += [expand_pattern(args.pattern, f) for f in parse_frames(args.frames)]
    if not paths:
        parser.error("no files")
    result = {}
    for path in paths:
        hashes = exr_hashes(path)
        result[path] = hashes
        print(f"{hashes['pixels']} {hashes['bytes']} {path}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(result, f, indent=1, sort_keys=True)
            f.write("\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
