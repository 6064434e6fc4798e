# SPDX-License-Identifier: Apache-2.0
"""Open Job Description: the template written by `drivenshape farm openjd` (JSON and YAML)
passes `openjd check` and openjd-model's own validation, and `openjd run` (openjd-cli from PyPI
in the project venv) runs its Bake step, one task per chunk, into outputs bitwise identical to a
local bake. Also runs a single chunk by --task-param, as a render manager retrying one task would.

Hostile values (issue 28): exit 0 always means a template openjd-model accepts. Values that
would land in a format string with `{{`/`}}` (OpenJD has no escape for them), control characters,
bytes that are not UTF-8, a cancel grace past OpenJD's 600 s and an output pattern every task's
bake would refuse (`a#b/c.####.exr`: 2 frame tokens) exit 2 naming the option and its value, and
write nothing."""

import json
import os
import subprocess
import sys
import time
from pathlib import Path

from farm_test_util import (FRAMES, check, check_template_with_openjd_model,
                            compare_report_with_reference, compare_with_reference, exr_files,
                            main, temp_files)


def openjd_tool():
    tool = Path(sys.executable).parent / "openjd"
    check(tool.is_file(), f"{tool} is missing: install openjd-cli into the venv "
                          f"(scripts/setup.sh installs scripts/requirements.txt)")
    return tool


def openjd(*words, timeout=300):
    command = [str(openjd_tool())] + [str(w) for w in words]
    started = time.monotonic()
    result = subprocess.run(command, capture_output=True, text=True, timeout=timeout)
    print(f"$ {' '.join(command)}  -> exit {result.returncode} in "
          f"{time.monotonic() - started:.1f} s", flush=True)
    check(result.returncode == 0, f"{' '.join(command)} failed ({result.returncode}):\n"
                                  f"{result.stdout[-4000:]}\n{result.stderr[-2000:]}")
    return result


def template_checks_and_runs(farm):
    folder = farm.scratch("openjd")
    out = folder / "out"
    job = folder / "shot.template.json"
    farm.run("farm", "openjd", "--db", farm.db, "--driver", farm.driver, "--frames", "1-48",
             "-o", out / "c.####.exr", "--chunk-size", "17", "--extra-args", "--batch 8",
             "--time", "0:10:00", "-O", job)
    template = json.loads(job.read_text())
    check(template["specificationVersion"] == "jobtemplate-2023-09",
          f"specificationVersion is {template['specificationVersion']}")
    space = template["steps"][0]["parameterSpace"]["taskParameterDefinitions"]
    check(space == [{"name": "Chunk", "type": "INT", "range": "0-2"}],
          f"the parameter space should be the 3 chunk indices, got {space}")
    params = folder / "shot.template.params.json"
    check(params.is_file(), f"{params} (job parameter values) was not written")
    openjd("check", job)
    check_template_with_openjd_model(job, params)

    yaml_job = folder / "shot.template.yaml"
    farm.run("farm", "openjd", "--db", farm.db, "--driver", farm.driver, "--frames", "1-48",
             "-o", out / "c.####.exr", "--chunk-size", "17", "--extra-args", "--batch 8",
             "--time", "0:10:00", "-O", yaml_job)
    openjd("check", yaml_job)
    check_template_with_openjd_model(yaml_job, params)
    import yaml  # openjd-cli depends on PyYAML
    check(yaml.safe_load(yaml_job.read_text()) == template,
          "the YAML template does not hold the same document as the JSON one")

    result = openjd("run", job, "--step", "Bake", "--job-param", f"file://{params}")
    check("Chunks run: 3" in result.stdout or "Tasks run: 3" in result.stdout,
          f"openjd run should run 3 tasks:\n{result.stdout[-3000:]}")
    check(not temp_files(out), f"temporary files left: {temp_files(out)}")
    compare_with_reference(farm, out)
    reports = sorted(p.name for p in out.glob("*.report.json"))
    check(reports == [f"c.chunk{i}.report.json" for i in range(3)],
          f"expected one report per chunk, got {reports}")
    # The Report step, after every chunk: the shot's report, the one-shot bake's.
    check(template["steps"][1]["dependencies"] == [{"dependsOn": "Bake"}],
          f"the Report step should depend on Bake: {template['steps'][1]}")
    result = openjd("run", job, "--step", "Report", "--job-param", f"file://{params}")
    check("baked 0 frames (48 kept)" in result.stdout,
          f"the Report step should keep all 48 frames:\n{result.stdout[-3000:]}")
    # The job's --extra-args give --batch 8: without the temporal bound it changes no cloth.
    compare_report_with_reference(farm, out / "c.report.json", settings_given=("batch",))

    # One task again (a retry): with --skip-existing everything is kept.
    (out / "c.0020.exr").unlink()
    result = openjd("run", job, "--step", "Bake", "--job-param", f"file://{params}",
                    "--task-param", "Chunk=1")
    check("baked 1 frames (16 kept)" in result.stdout,
          f"a rerun of chunk 1 should keep 16 frames and bake frame 20:\n{result.stdout[-3000:]}")
    check(len(exr_files(out)) == len(FRAMES), "frame 20 was not baked again")
    compare_with_reference(farm, out)


def hostile_values(farm):
    folder = farm.scratch("openjd-values")
    common = ["--db", farm.db, "--driver", farm.driver, "--frames", "1-48", "--chunk-size", "16"]

    # Written, and valid: quotes, '#', single braces, a space; '{{' in a folder (a PATH value,
    # never a format string); the longest cancel grace; a frame list longer than a description.
    long_frames = ",".join(str(f) for f in range(1, 3000, 2))
    accepted = [
        ["-o", folder / "out" / "c.####.exr", "--job-name", 'shot 10 #"x" {a} }b{ it\'s'],
        ["-o", folder / "out" / "c.####.exr", "--extra-args", "--batch 8 --device '{a}'"],
        ["-o", folder / "out {{a}}" / "c.####.exr", "--cancel-grace", "600"],
        ["-o", folder / "out" / "c{{x}}.####.exr", "--extra-args", "--report r.json"],
        ["-o", folder / "out" / "c.####.exr", "--job-name", "caf\u00e9 \u2014 \u00fc"],
    ]
    for i, words in enumerate(accepted):
        for suffix in (".json", ".yaml"):
            job = folder / f"ok{i}{suffix}"
            farm.run("farm", "openjd", *common, *words, "-O", job)
            check_template_with_openjd_model(job, folder / f"ok{i}.params.json")
        openjd("check", job)
    job = folder / "long.json"
    farm.run("farm", "openjd", "--db", farm.db, "--driver", farm.driver, "--frames", long_frames,
             "--chunk-size", "16", "--no-check", "-o", folder / "out" / "c.####.exr", "-O", job)
    check_template_with_openjd_model(job, folder / "long.params.json")

    # Refused, naming the option and the value; nothing written.
    refused = [
        (["--job-name", "shot {{Param.Database}}"], ["--job-name 'shot {{Param.Database}}'",
                                                     "{{"]),
        (["--job-name", "a }} b"], ["--job-name 'a }} b'"]),
        (["--extra-args", "--batch 8 --device {{x}}"], ["--extra-args '--batch 8 --device {{x}}'"]),
        (["--extra-args", "--device 'a\tb'"], ["--extra-args '--device 'a\\x09b''",
                                            "control character"]),
        (["--job-name", "a\u0085b"], ["--job-name 'a\\xc2\\x85b'"]),
        (["--cancel-grace", "601"], ["--cancel-grace 601", "1..600"]),
    ]
    out = ["-o", folder / "out" / "c.####.exr"]
    cases = [(out + words, words_in) for words, words_in in refused]
    cases.append((["-o", folder / "out" / "c{{x}}.####.exr"],
                  [f"-o '{folder}/out/c{{{{x}}}}.####.exr'", "--report"]))
    cases.append((["-o", folder / "a#b" / "c.####.exr"],
                  [f"-o '{folder}/a#b/c.####.exr'", "2 frame tokens"]))
    for words, expected in cases:
        job = folder / "refused.json"
        result = farm.run("farm", "openjd", *common, *words, "-O", job, expect=2)
        for text in expected:
            check(text in result.stderr, f"farm openjd {words}: the message lacks {text!r}:\n"
                                         f"{result.stderr}")
        check("usage error" in result.stderr, f"not a usage error: {result.stderr}")
        check(not job.exists() and not (folder / "refused.params.json").exists(),
              f"farm openjd {words} wrote a template despite exit 2")
    # A file name that is not UTF-8 would reach the template as U+FFFD: another path.
    job = folder / "refused.json"
    result = subprocess.run([bytes(farm.cli), b"farm", b"openjd", *map(os.fsencode, common),
                             b"-o", bytes(folder / "out") + b"/c\xff.####.exr", b"-O", bytes(job)],
                            capture_output=True, env=farm.env, timeout=60)
    stderr = result.stderr.decode(errors="replace")
    check(result.returncode == 2 and "-o '" in stderr and "UTF-8" in stderr,
          f"a path that is not UTF-8: exit {result.returncode}: {stderr}")
    check(not job.exists(), "a template was written for a path that is not UTF-8")
    # The bake refuses the same pattern with the same words: the farm command ran its check.
    result = farm.run(*farm.bake_args(folder / "a#b", frames="1"), expect=2)
    check("2 frame tokens" in result.stderr, result.stderr)


if __name__ == "__main__":
    sys.exit(main([hostile_values, template_checks_and_runs]))
