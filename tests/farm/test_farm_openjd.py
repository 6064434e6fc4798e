"""Open Job Description: the template written by `drivenshape farm openjd` (JSON and YAML)
passes `openjd check`, and `openjd run` (openjd-cli from PyPI in the project venv) runs its Bake
step, one task per chunk, into outputs bitwise identical to a local bake. Also runs a single
chunk by --task-param, as a render manager retrying one task would."""

import json
import subprocess
import sys
import time
from pathlib import Path

from farm_test_util import (FRAMES, check, compare_with_reference, exr_files, main, temp_files)


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

    yaml_job = folder / "shot.template.yaml"
    farm.run("farm", "openjd", "--db", farm.db, "--driver", farm.driver, "--frames", "1-48",
             "-o", out / "c.####.exr", "--chunk-size", "17", "--extra-args", "--batch 8",
             "--time", "0:10:00", "-O", yaml_job)
    openjd("check", yaml_job)
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

    # One task again (a retry): with --skip-existing everything is kept.
    (out / "c.0020.exr").unlink()
    result = openjd("run", job, "--step", "Bake", "--job-param", f"file://{params}",
                    "--task-param", "Chunk=1")
    check("baked 1 frames (16 kept)" in result.stdout,
          f"a rerun of chunk 1 should keep 16 frames and bake frame 20:\n{result.stdout[-3000:]}")
    check(len(exr_files(out)) == len(FRAMES), "frame 20 was not baked again")
    compare_with_reference(farm, out)


if __name__ == "__main__":
    sys.exit(main([template_checks_and_runs]))
