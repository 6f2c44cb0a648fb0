#!/usr/bin/env bash
# Checks, without rewriting anything, that every C++ source follows .clang-format (Debian 12's clang-format 14);
# prints the differences and exits non-zero if a file does not. To fix: clang-format -i <file>.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$here"
mapfile -t files < <(find core imaging segmentation phantom bench apps tests fuzz \
  \( -name '*.cpp' -o -name '*.h' -o -name '*.inc' \) -type f 2>/dev/null | sort)
if ! clang-format --dry-run --Werror "${files[@]}"; then
  echo "check-format: the files above differ from .clang-format (clang-format -i FILE rewrites one)" >&2
  exit 1
fi
echo "check-format: ${#files[@]} files follow .clang-format" >&2
