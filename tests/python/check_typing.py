#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""The module's types under mypy (the CTest python_typing; test_wheel.sh runs it on the installed
package too):

1. `mypy --strict` accepts the package's own modules (`-p drivenshape`: __init__.py, usd.py,
   qc.py, with the stubs _drivenshape.pyi), with no error at all;
2. `mypy --strict` accepts typing_example.py, which uses the main API;
3. mypy rejects typing_wrong.py with an error on exactly the lines marked `# wrong: CODE`, each
   with that error code, and on no other line (so a stub that says `typing.Any` fails here);
4. typing_example.py runs on the sleeve sample (the types describe working code).

Every mypy run reads the repository's pyproject.toml ([tool.mypy]: usd-core's `pxr` is untyped).

  check_typing.py --data tests/data/sleeve --work FOLDER [--mypy-path build/python]

--mypy-path is where mypy finds the package (the build tree); without it mypy finds the
installed one (site-packages, which py.typed makes it read).
"""
import argparse
import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
EXAMPLE = HERE / "typing_example.py"
WRONG = HERE / "typing_wrong.py"
CONFIG = HERE.parents[1] / "pyproject.toml"
ERROR_LINE = re.compile(r"^(?P<file>[^:]+):(?P<line>\d+): error: .*\[(?P<code>[a-z-]+)\]$")


def mypy(targets, work, mypy_path, strict):
    """mypy's exit status and output on `targets` (files, or `-p PACKAGE`)."""
    env = dict(os.environ)
    env.pop("MYPYPATH", None)
    if mypy_path:
        env["MYPYPATH"] = str(mypy_path)
    command = [sys.executable, "-m", "mypy", "--config-file", str(CONFIG), "--cache-dir",
               str(work / "mypy_cache"), "--no-error-summary", "--show-error-codes",
               "--no-pretty"]
    command += ["--strict"] if strict else []
    result = subprocess.run(command + [str(t) for t in targets], capture_output=True,
                            text=True, env=env, cwd=work)
    return result.returncode, result.stdout + result.stderr


def check_package(work, mypy_path):
    """The package's own Python (evaluate_cache, drivenshape.usd, drivenshape.qc) is annotated
    and checks under --strict against the stubs: any error fails."""
    status, output = mypy(["-p", "drivenshape"], work, mypy_path, strict=True)
    if status != 0 or output.strip():
        sys.exit(f"check_typing: mypy --strict rejects the package drivenshape ({status}):\n"
                 f"{output}")
    print("check_typing: mypy --strict accepts the package drivenshape (__init__, usd, qc)")


def check_example(work, mypy_path):
    status, output = mypy([EXAMPLE], work, mypy_path, strict=True)
    if status != 0:
        sys.exit(f"check_typing: mypy --strict rejects {EXAMPLE.name} ({status}):\n{output}")
    print(f"check_typing: mypy --strict accepts {EXAMPLE.name}")


def check_wrong(work, mypy_path):
    expected = {}
    for number, line in enumerate(WRONG.read_text().splitlines(), 1):
        mark = re.search(r"# wrong: ([a-z-]+)$", line)
        if mark:
            expected[number] = mark.group(1)
    status, output = mypy([WRONG], work, mypy_path, strict=False)
    found = {}
    for line in output.splitlines():
        match = ERROR_LINE.match(line)
        if match and Path(match["file"]).name == WRONG.name:
            found.setdefault(int(match["line"]), set()).add(match["code"])
    problems = [f"line {n}: expected a mypy error [{code}], got "
                f"{sorted(found[n]) if n in found else 'none'}"
                for n, code in expected.items() if code not in found.get(n, set())]
    problems += [f"line {n}: unexpected mypy error {sorted(codes)}"
                 for n, codes in found.items() if n not in expected]
    if status == 0 or problems or not expected:
        sys.exit(f"check_typing: {WRONG.name} is not rejected as marked (mypy exited "
                 f"{status}):\n  " + "\n  ".join(problems) + f"\nmypy said:\n{output}")
    print(f"check_typing: mypy rejects the {len(expected)} wrong uses of {WRONG.name}")


def run_example(data, work):
    out = work / "example"
    shutil.rmtree(out, ignore_errors=True)
    out.mkdir(parents=True)
    result = subprocess.run([sys.executable, str(EXAMPLE), str(data), str(out)],
                            capture_output=True, text=True)
    if result.returncode != 0:
        sys.exit(f"check_typing: {EXAMPLE.name} failed ({result.returncode}):\n"
                 f"{result.stdout}{result.stderr}")
    print(result.stdout.strip())


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--data", required=True, type=Path, help="tests/data/sleeve")
    parser.add_argument("--work", required=True, type=Path, help="a folder for mypy and the run")
    parser.add_argument("--mypy-path", type=Path, help="the package's folder (build/python)")
    args = parser.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    work = args.work.resolve()
    check_package(work, args.mypy_path and args.mypy_path.resolve())
    check_example(work, args.mypy_path and args.mypy_path.resolve())
    check_wrong(work, args.mypy_path and args.mypy_path.resolve())
    run_example(args.data.resolve(), work)
    return 0


if __name__ == "__main__":
    sys.exit(main())
