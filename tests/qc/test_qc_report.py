# SPDX-License-Identifier: Apache-2.0
"""scripts/qc_report.py on a real bake of the bundled sleeve, rendered in headless Chromium.

The command line builds the sample database, bakes 24 frames (host path: no OpenCL kernel build
in this test's time) and evaluates them against the simulated truth; qc_report.py writes the
page. Chromium must render it (a screenshot that is not blank and shows the plots' colours)
and load every image (a copy of the page with a small script that records each <img>'s decoded
size after the load event, read back with --dump-dom); each image is also checked here as a PNG
file. The summary table's numbers are compared with the report and eval JSON, read here, and the
worst vertex with per-vertex errors computed here from the truth PC2 (parsed byte by byte) and the
baked EXRs (OpenEXR PyPI package). A missing Chromium fails the test (scripts/setup.sh installs
the Debian package `chromium`)."""

import html.parser
import json
import os
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

FRAMES = "1-24"
FRAME_COUNT = 24
# The page prints figures with 6 significant digits.
PRINTED_RELATIVE_TOLERANCE = 1e-5
MM_PER_M = 1000.0
WINDOW = (1400, 3000)
# A rendered page: its luminance varies, and the plots' colours cover part of it (text alone is
# black on white). Measured on the sample: standard deviation 50, 11% colourful pixels.
MIN_LUMINANCE_STD = 20.0
MIN_COLOURFUL_FRACTION = 0.03
EXPECTED_IMAGES = {"error.png", "heatmap.png", "weights.png", "residual.png", "audit.png",
                   "jump.png"}


def run(command, expect=0, **kwargs):
    result = subprocess.run([str(c) for c in command], capture_output=True, text=True,
                            timeout=120, **kwargs)
    assert result.returncode == expect, (
        f"{' '.join(map(str, command))} exited {result.returncode}, expected {expect}:\n"
        f"{result.stdout}{result.stderr}")
    return result


def qc(script, *args, expect=0):
    return run([sys.executable, script, *args], expect=expect)


def chromium():
    path = shutil.which("chromium")
    assert path, "headless Chromium is missing: install the Debian package chromium " \
                 "(scripts/setup.sh does)"
    return path


def chromium_run(root, *args):
    """Headless Chromium with its profile in the test's folder (never the user's)."""
    return run([chromium(), "--headless", "--no-sandbox", "--disable-gpu",
                f"--user-data-dir={root / 'chromium-profile'}", *args])


# ---- independent readers ---------------------------------------------------------------------

def parse_pc2(path):
    raw = Path(path).read_bytes()
    assert raw[:12] == b"POINTCACHE2\0", f"{path}: no PC2 magic"
    points = int(np.frombuffer(raw[16:20], "<i4")[0])
    start = float(np.frombuffer(raw[20:24], "<f4")[0])
    samples = int(np.frombuffer(raw[28:32], "<i4")[0])
    xyz = np.frombuffer(raw, "<f4", offset=32).reshape(samples, points, 3)
    return xyz, int(round(start))


def read_exr(path):
    import OpenEXR

    with OpenEXR.File(str(path), separate_channels=True) as image:
        count = int(image.header()["dsVertexCount"])
        channels = image.channels()
        return np.stack([np.asarray(channels[c].pixels, np.float32).reshape(-1)[:count]
                         for c in ("P.X", "P.Y", "P.Z")], axis=1)


class PageParser(html.parser.HTMLParser):
    """The page's <img> sources, its summary table as {data-key: text}, the worst frames' links
    and the per-frame table as {frame: [cell texts]} (rows with id frame-N)."""

    def __init__(self):
        super().__init__()
        self.images, self.summary, self.worst, self.frames = [], {}, [], {}
        self._key = None
        self._row = None
        self._in_worst = False

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "img":
            self.images.append(attrs.get("src"))
        elif tag == "td" and "data-key" in attrs:
            self._key = attrs["data-key"]
            self.summary[self._key] = ""
        elif tag == "tr" and (attrs.get("id") or "").startswith("frame-"):
            self._row = self.frames.setdefault(int(attrs["id"][len("frame-"):]), [])
        elif tag == "td" and self._row is not None:
            self._row.append("")
        elif tag == "p" and attrs.get("id") == "worst":
            self._in_worst = True
        elif tag == "a" and self._in_worst:
            self.worst.append(attrs["href"])

    def handle_endtag(self, tag):
        if tag == "td":
            self._key = None
        elif tag == "tr":
            self._row = None
        elif tag == "p":
            self._in_worst = False

    def handle_data(self, data):
        if self._key:
            self.summary[self._key] += data
        elif self._row:
            self._row[-1] += data


def parse_page(path):
    parser = PageParser()
    parser.feed(Path(path).read_text(encoding="utf-8"))
    return parser


def png_size(path):
    raw = Path(path).read_bytes()
    assert raw[:8] == b"\x89PNG\r\n\x1a\n", f"{path} is not a PNG"
    assert raw[12:16] == b"IHDR", f"{path}: no IHDR chunk first"
    return struct.unpack(">II", raw[16:24])


# ---- the sample, baked and evaluated once ----------------------------------------------------

@pytest.fixture(scope="session")
def script(request):
    return request.config.getoption("--script")


@pytest.fixture(scope="session")
def data(request):
    return Path(request.config.getoption("--data"))


@pytest.fixture(scope="session")
def sample(request, data, tmp_path_factory):
    cli = request.config.getoption("--cli")
    assert os.access(cli, os.X_OK), f"the command line {cli} is not built"
    root = tmp_path_factory.mktemp("sample")
    db = root / "sleeve.dsdb"
    run([cli, "db", "build", "--driver-mesh", data / "driver_rest.obj", "--driven-mesh",
         data / "driven_rest.obj", "--driver", data / "train.driver.pc2", "--driven",
         data / "train.driven.pc2", "--model", "none", "--quiet", "-o", db])
    (root / "bake").mkdir()
    run([cli, "bake", "--db", db, "--driver", data / "test.driver.pc2", "--frames", FRAMES,
         "--device", "host", "--quiet", "-o", root / "bake" / "sleeve.####.exr"])
    run([cli, "eval", "--truth", data / "test.driven.pc2", "--bake",
         root / "bake" / "sleeve.####.exr", "--frames", FRAMES, "--driver",
         data / "test.driver.pc2", "--db", db, "--baseline", "--json", root / "eval.json"])
    report = root / "bake" / "sleeve.report.json"
    return {"root": root, "report": report, "eval": root / "eval.json",
            "report_json": json.loads(report.read_text()),
            "eval_json": json.loads((root / "eval.json").read_text())}


@pytest.fixture(scope="session")
def page(sample, script, data):
    out = sample["root"] / "qc"
    result = qc(script, "--report", sample["report"], "--eval", sample["eval"], "--mesh",
                data / "driven_rest.obj", "--units", "m", "-o", out)
    assert result.stdout.strip() == f"qc: {out / 'index.html'}", result.stdout
    return out / "index.html"


# ---- rendering -------------------------------------------------------------------------------

def test_page_renders_in_chromium(page, sample):
    from PIL import Image

    shot = sample["root"] / "screenshot.png"
    chromium_run(sample["root"], f"--screenshot={shot}",
                 f"--window-size={WINDOW[0]},{WINDOW[1]}", page.as_uri())
    image = np.asarray(Image.open(shot).convert("RGB"), dtype=np.float64)
    assert image.shape[:2] == (WINDOW[1], WINDOW[0]), f"screenshot is {image.shape}"
    luminance = image @ np.array([0.299, 0.587, 0.114])
    colourful = (image.max(axis=2) - image.min(axis=2)) > 60
    print(f"screenshot: luminance std {luminance.std():.1f} (threshold {MIN_LUMINANCE_STD}), "
          f"colourful pixels {colourful.mean():.3f} (threshold {MIN_COLOURFUL_FRACTION})")
    assert luminance.std() > MIN_LUMINANCE_STD, "the screenshot is (nearly) one colour"
    assert colourful.mean() > MIN_COLOURFUL_FRACTION, "the screenshot shows no plots"


LOAD_CHECK = """<script>
window.addEventListener("load", function () {
  var found = [];
  for (var i = 0; i < document.images.length; ++i) {
    var image = document.images[i];
    found.push({src: image.getAttribute("src"), complete: image.complete,
                width: image.naturalWidth, height: image.naturalHeight});
  }
  var out = document.createElement("pre");
  out.id = "image-check";
  out.textContent = JSON.stringify(found);
  document.body.appendChild(out);
});
</script>
"""


def test_every_image_loads(page, sample):
    parsed = parse_page(page)
    assert set(parsed.images) >= EXPECTED_IMAGES, f"images on the page: {parsed.images}"
    # Chromium: a copy of the page with a script that records every image after the load
    # event (a broken image has naturalWidth 0); the report itself has no script.
    copy = sample["root"] / "qc_checked"
    shutil.copytree(page.parent, copy)
    text = (copy / "index.html").read_text(encoding="utf-8")
    assert "<script" not in text, "the page should need no JavaScript"
    (copy / "index.html").write_text(text.replace("</body>", LOAD_CHECK + "</body>"),
                                     encoding="utf-8")
    dom = chromium_run(sample["root"], "--dump-dom", "--virtual-time-budget=10000",
                       (copy / "index.html").as_uri()).stdout
    start = dom.find('<pre id="image-check">')
    assert start >= 0, "Chromium did not run the load check"
    body = dom[start + len('<pre id="image-check">'):dom.index("</pre>", start)]
    loaded = json.loads(html.unescape(body))
    assert [entry["src"] for entry in loaded] == parsed.images
    for entry in loaded:
        assert entry["complete"] and entry["width"] > 0 and entry["height"] > 0, \
            f"Chromium did not load {entry}"
    # The files themselves: relative links to PNGs beside the page, with their declared size.
    for src in parsed.images:
        assert not os.path.isabs(src) and "/" not in src, f"not a relative link beside it: {src}"
        width, height = png_size(page.parent / src)
        entry = next(e for e in loaded if e["src"] == src)
        assert (entry["width"], entry["height"]) == (width, height), src


# ---- numbers ---------------------------------------------------------------------------------

def assert_printed(summary, key, expected):
    assert key in summary, f"no '{key}' in the summary table: {sorted(summary)}"
    value = float(summary[key])
    assert value == pytest.approx(expected, rel=PRINTED_RELATIVE_TOLERANCE, abs=1e-12), (
        f"summary '{key}': page {value}, expected {expected} "
        f"(relative tolerance {PRINTED_RELATIVE_TOLERANCE})")


def test_summary_matches_the_json(page, sample, data):
    summary = parse_page(page).summary
    report, evaluation = sample["report_json"], sample["eval_json"]
    baked = [r for r in report["frames"] if not r["skipped"]]
    assert len(baked) == FRAME_COUNT and int(summary["frames_baked"]) == len(baked)

    # The page shows the direct residual (this version's reports all have it).
    residuals = [r["relative_residual_direct"] for r in baked]
    assert_printed(summary, "residual_mean", sum(residuals) / len(residuals))
    assert_printed(summary, "residual_max", max(residuals))
    for key in ("inside_corrected", "inside_after"):
        values = [r[key] for r in baked]
        assert_printed(summary, f"{key}_mean", sum(values) / len(values))
        assert_printed(summary, f"{key}_max", max(values))
    assert int(summary["resolved_total"]) == sum(r["resolved"] for r in baked)
    jumps = [r["max_jump"] for r in baked if "max_jump" in r]
    assert_printed(summary, "max_jump", max(jumps) * MM_PER_M)

    assert_printed(summary, "error_mean", evaluation["mean"] * MM_PER_M)
    assert_printed(summary, "error_rms", evaluation["rms"] * MM_PER_M)
    assert_printed(summary, "error_max", evaluation["max"] * MM_PER_M)
    assert_printed(summary, "baseline_error_mean",
                   evaluation["summary"]["baseline"]["mean"] * MM_PER_M)

    # The worst frames by max error, ranked here from the eval's frames.
    ranked = sorted(evaluation["frames"], key=lambda r: (-r["max"], r["frame"]))
    assert parse_page(page).worst == [f"#frame-{r['frame']}" for r in ranked[:5]]

    # The worst vertex, from per-vertex errors computed here without the module.
    truth, start = parse_pc2(data / "test.driven.pc2")
    frames = [r["frame"] for r in evaluation["frames"]]
    baked_xyz = np.stack([read_exr(sample["root"] / "bake" / f"sleeve.{f:04d}.exr")
                          for f in frames]).astype(np.float64)
    distance = np.linalg.norm(baked_xyz - truth[[f - start for f in frames]], axis=2)
    assert distance.mean(axis=1) == pytest.approx([r["mean"] for r in evaluation["frames"]],
                                                  rel=1e-5), "the test's reader disagrees"
    per_vertex = distance.mean(axis=0)
    assert int(summary["worst_vertex"]) == int(per_vertex.argmax())
    assert_printed(summary, "worst_vertex_error", per_vertex.max() * MM_PER_M)


def test_frame_table_matches_the_json(page, sample):
    rows = parse_page(page).frames
    evaluation = {r["frame"]: r for r in sample["eval_json"]["frames"]}
    assert sorted(rows) == [r["frame"] for r in sample["report_json"]["frames"]]
    for record in sample["report_json"]["frames"]:
        frame = record["frame"]
        cells = rows[frame]
        assert int(cells[0]) == frame
        assert float(cells[2]) == pytest.approx(record["relative_residual_direct"],
                                                rel=PRINTED_RELATIVE_TOLERANCE)
        assert int(cells[4]) == record["inside_after"] and int(cells[5]) == record["resolved"]
        assert float(cells[7]) == pytest.approx(evaluation[frame]["mean"] * MM_PER_M,
                                                rel=PRINTED_RELATIVE_TOLERANCE)
        assert float(cells[8]) == pytest.approx(evaluation[frame]["max"] * MM_PER_M,
                                                rel=PRINTED_RELATIVE_TOLERANCE)


def test_coverage_section(page, sample, script):
    assert "No coverage check in this report." in page.read_text(encoding="utf-8")
    # Chunk reports (two halves of the bake) with coverage entries on three frames: the page
    # merges them and lists the flagged frames.
    report = sample["report_json"]
    flagged = {5, 6, 17}
    halves = []
    for index, part in enumerate((report["frames"][:12], report["frames"][12:])):
        chunk = dict(report, frames=[dict(r, coverage={"flagged": r["frame"] in flagged,
                                                       "score": r["frame"] / 10.0})
                                     for r in part])
        path = sample["root"] / f"chunk{index}.report.json"
        path.write_text(json.dumps(chunk))
        halves += ["--report", path]
    out = sample["root"] / "qc_coverage"
    qc(script, *halves, "-o", out)
    text = (out / "index.html").read_text(encoding="utf-8")
    parsed = parse_page(out / "index.html")
    assert int(parsed.summary["frames_baked"]) == FRAME_COUNT
    assert "No coverage check" not in text
    listed = text[text.index("Frames the coverage check flagged"):]
    listed = listed[:listed.index("</p>")]
    assert "(3 of 24 checked)" in listed
    for frame in flagged:
        assert f'href="#frame-{frame}"' in listed
    assert "coverage.png" in parsed.images and (out / "coverage.png").stat().st_size > 0


# ---- errors ----------------------------------------------------------------------------------

def test_help_and_usage(script):
    assert "--report" in qc(script, "--help").stdout
    assert "--report" in qc(script, expect=2).stderr
    result = qc(script, "--report", "r.json", "--truth", "t.pc2", "-o", "x", expect=2)
    assert "--mesh" in result.stderr


def test_missing_report_is_an_input_error(script, tmp_path):
    missing = tmp_path / "nowhere" / "shot.report.json"
    out = tmp_path / "qc"
    result = qc(script, "--report", missing, "-o", out, expect=3)
    assert str(missing) in result.stderr and "does not exist" in result.stderr, result.stderr
    assert not out.exists()


def test_failures_leave_no_report(script, sample, data, tmp_path):
    out = tmp_path / "qc"
    bad = tmp_path / "eval.json"
    bad.write_text("{ not json")
    result = qc(script, "--report", sample["report"], "--eval", bad, "-o", out, expect=3)
    assert str(bad) in result.stderr
    # Another truth than the one eval compared with (same vertex count): refused.
    result = qc(script, "--report", sample["report"], "--eval", sample["eval"], "--mesh",
                data / "driven_rest.obj", "--truth", data / "train.driven.pc2", "-o", out,
                expect=3)
    assert "train.driven.pc2" in result.stderr
    assert list(tmp_path.iterdir()) == [bad], "a failed run left files behind"
    # A folder that is not a QC report is never replaced.
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    result = qc(script, "--report", sample["report"], "-o", out, expect=4)
    assert "not a QC report" in result.stderr
    assert [p.name for p in out.iterdir()] == ["keep.txt"]


def test_rewrite_replaces_an_earlier_report(script, sample, tmp_path):
    out = tmp_path / "qc"
    qc(script, "--report", sample["report"], "-o", out)
    (out / "stale.png").write_bytes(b"old")
    qc(script, "--report", sample["report"], "--title", "second", "-o", out)
    assert not (out / "stale.png").exists()
    assert "<title>second</title>" in (out / "index.html").read_text(encoding="utf-8")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["qc"], "temporary folders left"
