#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Fails when a source file (tracked, or new and not ignored by git) lacks its SPDX license line:
# line 1, or line 2 after a `#!` shebang, must read `// SPDX-License-Identifier: Apache-2.0`
# (C, C++, OpenCL) or `# SPDX-License-Identifier: Apache-2.0` (Python, its .pyi stubs and py.typed
# markers, shell, CMake, YAML, TOML, other scripts with a shebang). Data (tests/data, the fuzz
# seeds and regressions), Markdown, JSON, meshes, caches, images and dot-files such as
# .clang-format are not sources: not checked.
#   scripts/check_spdx.sh          check (CTest: spdx_check)
#   scripts/check_spdx.sh --fix    add the line where it is missing, then check
set -euo pipefail
cd "$(dirname "$0")/.."

fix=0
if [[ ${1:-} == --fix ]]; then fix=1; elif (($#)); then
  echo "usage: $0 [--fix]" >&2
  exit 2
fi
license='SPDX-License-Identifier: Apache-2.0'

# The comment that starts the SPDX line of FILE, or nothing when FILE is not a source.
comment_of() {
  local file=$1 first=""
  case $file in
    tests/data/* | tests/fuzz/corpus/* | tests/fuzz/regressions/*) return ;;
    *.cpp | *.h | *.cl | *.cxx | *.hpp | *.cc | *.c) echo "//" ;;
    *.py | *.pyi | */py.typed | *.sh | *.cmake | *.cmake.in | CMakeLists.txt | */CMakeLists.txt | \
      *.yml | *.yaml | *.toml) echo "#" ;;
    *.md | *.json | *.obj | *.pc2 | *.exr | *.dsdb | *.png | *.txt) return ;;
    .clang-format | .gitignore | .gitattributes | */.gitignore | */.gitattributes) return ;;
    *) # an extension-less script: a shell or Python shebang
      IFS= read -r first <"$file" || true
      if [[ $first == '#!'*sh* || $first == '#!'*python* ]]; then echo "#"; fi ;;
  esac
}

mapfile -t files < <(git ls-files --cached --others --exclude-standard 2>/dev/null ||
  find . -type f ! -path './.git/*' ! -path './build*' ! -path './.venv/*' ! -path './out/*' |
  sed 's|^\./||')
checked=0
missing=()
for file in "${files[@]}"; do
  [[ -f $file ]] || continue
  comment=$(comment_of "$file")
  [[ -n $comment ]] || continue
  checked=$((checked + 1))
  want="$comment $license"
  line1="" line2=""
  { IFS= read -r line1 || true; IFS= read -r line2 || true; } <"$file"
  if [[ $line1 == "$want" || ($line1 == '#!'* && $line2 == "$want") ]]; then continue; fi
  if ((fix)); then
    if [[ $line1 == '#!'* ]]; then
      sed -i "1a $want" "$file"
    elif [[ -s $file ]]; then
      sed -i "1i $want" "$file"
    else
      printf '%s\n' "$want" >"$file"
    fi
    echo "spdx: added the license line to $file"
  else
    missing+=("$file")
  fi
done

if ((${#missing[@]})); then
  for file in "${missing[@]}"; do
    echo "spdx: $file: no '$license' line on line 1 (line 2 after a #! line)" >&2
  done
  echo "spdx: ${#missing[@]} of $checked source files lack the license line" \
    "(scripts/check_spdx.sh --fix adds it)" >&2
  exit 1
fi
echo "spdx: ${checked} source files carry the license line"
