#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The repository stands alone: no file refers to a design page it does not have or to folders
# beside the clone. Fails naming each line that points outside (docs/contributing.md).
#
#   bash scripts/check_standalone.sh
set -euo pipefail
cd "$(dirname "$0")/.."
# Spelled in two parts so that this file does not match itself.
design='DESIGN''\.md'
beside='\.\./''shared'
if hits=$(grep -rnIE "$design|$beside" . --exclude-dir=.git --exclude-dir='build*' \
  --exclude-dir=.venv --exclude-dir=out --exclude-dir=__pycache__); then
  echo "$hits" >&2
  echo "check_standalone: the lines above point outside the repository; say it in docs/ instead" >&2
  exit 1
fi
echo "check_standalone: nothing points outside the repository"
