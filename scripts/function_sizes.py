#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Lists the longest functions in C++ and Python sources (lines from signature to end of body).

  scripts/function_sizes.py [--top N] [--rev COMMIT] [--max PATH=N,...] [PATHS...]
                                                     (default: src, or the --max paths)

C++ (.cpp, .h): a brace-matching heuristic, not a parser: a function starts at a line that
opens a block after a parameter list `(...)` and is not a control statement, a lambda, a class
or a namespace; it ends at the matching brace. Comments and string literals are stripped first.
Python (.py): parsed with the `ast` module; every function and method (a `def` at module level
or in a class body, classes nested or not) counts from its `def` line to the last line of its
body (end_lineno; decorators excluded, its docstring and nested functions included), named
`Class.method` for methods. With --rev the files are read from that commit (git show), to
compare before and after a change.

With --max (e.g. `--max apps=80,src=120`, the limits of docs/contributing.md and of the CTest
function_sizes), every function under a PATH longer than its N lines is listed after the top
ones, and the exit status is 1 if there is any (the longest PATH that holds a file sets its
limit; files under no PATH have none).
"""
import argparse
import ast
import re
import subprocess
import sys
from pathlib import Path

CONTROL = re.compile(r"^\s*(if|for|while|switch|catch|else|do|return|case)\b")
NOT_FUNCTION = re.compile(r"\b(class|struct|namespace|enum|union)\b|\[[^\]]*\]\s*\(|=\s*\[|^\s*\[")


def strip(text):
    text = re.sub(r"/\*.*?\*/", lambda m: "\n" * m.group(0).count("\n"), text, flags=re.S)
    text = re.sub(r"//[^\n]*", "", text)
    text = re.sub(r'"(\\.|[^"\\\n])*"', '""', text)
    text = re.sub(r"'(\\.|[^'\\\n])*'", "''", text)
    return text


def functions(path, text):
    lines = strip(text).split("\n")
    found = []
    depth = 0
    stack = []  # (depth at open, start line, is function, signature)
    pending = ""
    for number, line in enumerate(lines, 1):
        for i, char in enumerate(line):
            if char == "{":
                head = (pending + " " + line[:i]).strip()
                is_function = (
                    ")" in head[-200:]
                    and not CONTROL.search(head.split(";")[-1].split("}")[-1])
                    and not NOT_FUNCTION.search(head.split(";")[-1].split("}")[-1])
                    and not any(s[2] for s in stack)  # nested blocks belong to their function
                )
                start = number
                # the signature may start on earlier lines
                signature = head.split(";")[-1].split("}")[-1].strip()
                stack.append((depth, start, is_function, signature))
                depth += 1
                pending = ""
            elif char == "}":
                depth -= 1
                if stack:
                    _, start, is_function, signature = stack.pop()
                    if is_function:
                        name = re.sub(r"\s+", " ", signature)[:90]
                        found.append((number - start + 1, path, start, name))
                pending = ""
        pending += " " + line if "{" not in line and "}" not in line else ""
        if line.strip().endswith(";"):
            pending = ""
    return found


def python_functions(path, text):
    """(length, path, start line, name) of every function and method of a Python source."""
    found = []

    def visit(node, prefix):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                length = child.end_lineno - child.lineno + 1
                found.append((length, path, child.lineno, f"def {prefix}{child.name}"))
            elif isinstance(child, ast.ClassDef):
                visit(child, f"{prefix}{child.name}.")

    visit(ast.parse(text, filename=path), "")
    return found


SOURCES = {".cpp": functions, ".h": functions, ".py": python_functions}


def parse_limits(text):
    """`apps=80,src=120` -> {("apps",): 80, ("src",): 120} (paths as their parts)."""
    limits = {}
    for item in text.split(","):
        path, _, lines = item.partition("=")
        if not path.strip() or not lines.strip().isdigit():
            raise argparse.ArgumentTypeError(f"--max takes PATH=N,... (got '{item}')")
        limits[Path(path.strip()).parts] = int(lines)
    return limits


def limit_of(path, limits):
    """The limit of the longest path in `limits` that holds `path`, or None."""
    parts = Path(path).parts
    held = [key for key in limits if parts[: len(key)] == key]
    return limits[max(held, key=len)] if held else None


def report_over(results, limits):
    """Prints the functions over their limit; returns how many there are."""
    over = [(length, path, start, name, limit)
            for length, path, start, name in results
            for limit in [limit_of(path, limits)]
            if limit is not None and length > limit]
    spelled = ", ".join(f"{'/'.join(key)} {lines}" for key, lines in limits.items())
    if not over:
        print(f"no function over the limits (lines: {spelled})")
        return 0
    print(f"{len(over)} function(s) over the limits (lines: {spelled}); split them into steps "
          "(docs/contributing.md):")
    for length, path, start, name, limit in over:
        print(f"{length:5d}  {path}:{start}  {name.rstrip()}  (limit {limit})")
    return len(over)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("paths", nargs="*")
    parser.add_argument("--top", type=int, default=5)
    parser.add_argument("--rev")
    parser.add_argument("--max", type=parse_limits, metavar="PATH=N,...",
                        help="fail (exit 1) when a function under PATH is over N lines")
    args = parser.parse_args()
    if not args.paths:
        args.paths = ["/".join(key) for key in args.max] if args.max else ["src"]
    results = []
    if args.rev:
        names = subprocess.run(["git", "ls-tree", "-r", "--name-only", args.rev, *args.paths],
                               capture_output=True, text=True, check=True).stdout.split()
        for name in names:
            reader = SOURCES.get(Path(name).suffix)
            if reader:
                text = subprocess.run(["git", "show", f"{args.rev}:{name}"], capture_output=True,
                                      text=True, check=True).stdout
                results += reader(name, text)
    else:
        for root in args.paths:
            for path in sorted(Path(root).rglob("*")):
                reader = SOURCES.get(path.suffix)
                if reader and path.is_file():
                    results += reader(str(path), path.read_text(errors="replace"))
    results.sort(reverse=True)
    for length, path, start, name in results[: args.top]:
        print(f"{length:5d}  {path}:{start}  {name}")
    if args.max:
        return 1 if report_over(results, args.max) else 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
