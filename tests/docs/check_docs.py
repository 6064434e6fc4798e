# SPDX-License-Identifier: Apache-2.0
"""Checks that the documentation stays a front door a user can follow: the README keeps the two
commands on top and stays within 150 lines, `.ci/run` runs the second of them, and every
relative link in README.md and docs/*.md names a file that exists and, with a #fragment, a
heading in it. Exit 1 with one line per problem."""
import pathlib
import re
import sys

ROOT = pathlib.Path(__file__).resolve().parents[2]
README_MAX_LINES = 150
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")


def slug(heading):
    """The anchor GitHub gives a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r"[`*_]", "", heading.strip().lower())
    text = re.sub(r"[^\w\- ]", "", text)
    return text.replace(" ", "-")


def anchors(path):
    found, fenced = set(), False
    for line in path.read_text(encoding="utf-8").splitlines():
        if line.startswith("```"):
            fenced = not fenced
        elif not fenced and line.startswith("#"):
            found.add(slug(line.lstrip("#")))
    return found


def link_problems(page):
    problems, fenced = [], False
    for number, line in enumerate(page.read_text(encoding="utf-8").splitlines(), 1):
        if line.startswith("```"):
            fenced = not fenced
            continue
        if fenced:
            continue
        for target in LINK.findall(line):
            if re.match(r"[a-z]+:", target):
                continue  # http:, https:, mailto:
            name, _, fragment = target.partition("#")
            where = (page.parent / name).resolve() if name else page
            if not where.exists():
                problems.append(f"{page.relative_to(ROOT)}:{number}: '{target}': no such file")
            elif fragment and where.suffix == ".md" and fragment not in anchors(where):
                problems.append(f"{page.relative_to(ROOT)}:{number}: '{target}': no heading "
                                f"'#{fragment}' in {where.relative_to(ROOT)}")
    return problems


def readme_problems():
    lines = (ROOT / "README.md").read_text(encoding="utf-8").splitlines()
    problems = []
    if len(lines) > README_MAX_LINES:
        problems.append(f"README.md: {len(lines)} lines, more than {README_MAX_LINES}; move "
                        "detail (measurements above all) into docs/")
    commands = [line.split("#")[0].strip() for line in lines[:12] if line.startswith("bash ")]
    if commands != ["bash scripts/demo.sh", "bash scripts/test.sh"]:
        problems.append(f"README.md: the first commands are {commands}, not the demo and the "
                        "test command")
    ci = (ROOT / ".ci" / "run").read_text(encoding="utf-8")
    if "bash scripts/test.sh" not in ci:
        problems.append(".ci/run does not run the README's test command, bash scripts/test.sh")
    return problems


def main():
    problems = readme_problems()
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        problems += link_problems(page)
    for problem in problems:
        print(problem)
    print(f"docs_check: {len(problems)} problem(s)")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
