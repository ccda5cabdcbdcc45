#!/usr/bin/env bash
# Every C++ source, OpenCL kernel and GLSL shader of the project is as clang-format writes it
# (.clang-format at the root). Prints the lines that are not, and their files.
# Usage: format_check.sh SOURCE_DIR. The style is clang-format 14's, Debian 12's: another
# version formats some lines otherwise, so the check is skipped there (exit 77), not passed.
set -euo pipefail
root=$1
fmt=$(command -v clang-format-14 || command -v clang-format || true)
if [ -z "$fmt" ]; then
  echo "format_check: no clang-format (Debian package clang-format)" >&2
  exit 1
fi
version=$("$fmt" --version | sed -E 's/.*version ([0-9]+).*/\1/')
if [ "$version" != 14 ]; then
  echo "format_check: skipped: clang-format $version, the style is clang-format 14's"
  exit 77
fi
cd "$root"
files=$(find server client tests kernels shaders proto -type f \
  \( -name '*.cpp' -o -name '*.h' -o -name '*.cl' -o -name '*.comp' -o -name '*.glsl' \) |
  sort)
count=$(echo "$files" | wc -l)
# One clang-format for all files (one a file took 30 times as long); it names each line that
# it would write otherwise.
if ! report=$(echo "$files" | xargs "$fmt" --dry-run --Werror 2>&1); then
  echo "$report" | head -60
  echo "format_check: $count files; not formatted (clang-format -i FILE):"
  echo "$report" | grep -oE '^[^: ]+:[0-9]+:[0-9]+: error' | cut -d: -f1 | sort -u
  exit 1
fi
echo "format_check: $count files, all formatted"
