#!/usr/bin/env bash
# `lint-imports` (the layer contracts in pyproject.toml) over the package as installed: probeless/
# with messages/ and nodes/ mapped in as probeless.messages and probeless.nodes (setuptools
# package-dir), which import-linter cannot see from the source tree alone. It reads a view made of
# symbolic links, so line numbers and paths in its report are the repository's.
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$PWD
view=$(mktemp -d)
trap 'rm -rf "$view"' EXIT
mkdir "$view/probeless"
for entry in probeless/*; do ln -s "$repo/$entry" "$view/probeless/"; done
ln -s "$repo/messages" "$view/probeless/messages"
ln -s "$repo/nodes" "$view/probeless/nodes"
cd "$view"
PYTHONPATH="$view" "$repo/.venv/bin/lint-imports" "${LINT_IMPORTS_CONFIG:-$repo/pyproject.toml}" "$@"
