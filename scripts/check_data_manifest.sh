#!/usr/bin/env bash
# Checks that every file tests/data_manifest.txt lists is present in the data folder
# (argument, or $VFXGRAPH_SHARED_DATA, or ../shared/data beside the clone). Exit 1 naming the
# first missing file. .ci/run calls it before building.
set -euo pipefail
cd "$(dirname "$0")/.."
data="${1:-${VFXGRAPH_SHARED_DATA:-../shared/data}}"
if [ ! -d "$data" ]; then
  echo "error: the test data folder $data is missing (tests read the real data there)" >&2
  exit 1
fi
n=0
while IFS= read -r line || [ -n "$line" ]; do
  f="${line%%#*}"
  f="$(echo "$f" | xargs)"
  [ -z "$f" ] && continue
  if [ ! -f "$data/$f" ]; then
    echo "error: test data missing: $data/$f (listed in tests/data_manifest.txt)" >&2
    exit 1
  fi
  n=$((n + 1))
done < tests/data_manifest.txt
echo "test data: all $n files of tests/data_manifest.txt present in $data"
