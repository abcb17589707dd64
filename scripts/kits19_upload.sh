#!/usr/bin/env bash
# Uploads the twelve KiTS19 label volumes to a running cohortforge service and prints, per
# case, the kidney mesh record: volume of the mesh against the voxel-counted volume of the
# selected label component, vertex count, closedness, and the upload time.
#
# Usage (service running, e.g. `cargo run --release`):
#   scripts/kits19_upload.sh [BASE_URL] [EXTRA_QUERY]
#   scripts/kits19_upload.sh http://127.0.0.1:8080 'target_vertices=2000'
#
# Environment: KITS19_DIR (default ../shared/data/kits19/segmentations relative to the
# repository), COHORTFORGE_TOKEN (sent as a bearer token when set).
# Needs curl and python3.
set -euo pipefail

BASE_URL="${1:-http://127.0.0.1:8080}"
EXTRA_QUERY="${2:-}"
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
KITS19_DIR="${KITS19_DIR:-$HERE/../../shared/data/kits19/segmentations}"

if [ ! -d "$KITS19_DIR" ]; then
  echo "no label volumes at $KITS19_DIR (set KITS19_DIR)" >&2
  exit 1
fi

AUTH=()
if [ -n "${COHORTFORGE_TOKEN:-}" ]; then
  AUTH=(-H "authorization: Bearer $COHORTFORGE_TOKEN")
fi

DATASET=$(curl -sf "${AUTH[@]}" -X POST "$BASE_URL/v1/datasets" \
  -H 'content-type: application/json' \
  -d '{"name": "kits19 kidneys", "organ": "kidney"}' \
  | python3 -c 'import json,sys; print(json.load(sys.stdin)["id"])')
echo "dataset $DATASET"

# Label 1 (kidney), largest 6-connected component, cavities filled, 1.5 mm voxels, sigma 1 mm.
QUERY="label=1&component=largest&fill_holes=true&voxel_mm=1.5&smooth_sigma_mm=1"
if [ -n "$EXTRA_QUERY" ]; then
  QUERY="$QUERY&$EXTRA_QUERY"
fi

printf '%-12s %10s %10s %8s %9s %6s %6s %8s\n' case mesh_ml voxel_ml diff_% vertices closed euler seconds
for volume in "$KITS19_DIR"/case_*.nii.gz; do
  name=$(basename "$volume" .nii.gz)
  response=$(curl -s "${AUTH[@]}" -w '\n%{http_code} %{time_total}' -X POST \
    "$BASE_URL/v1/datasets/$DATASET/meshes?name=$name&$QUERY" \
    -H 'content-type: application/x-nifti' --data-binary "@$volume")
  status_line=$(printf '%s\n' "$response" | tail -n 1)
  body=$(printf '%s\n' "$response" | sed '$d')
  read -r status seconds <<<"$status_line"
  if [ "$status" != "201" ]; then
    echo "$name: HTTP $status $body"
    continue
  fi
  printf '%s\n' "$body" | python3 -c '
import json, sys
r = json.load(sys.stdin)
s = r["source"]
diff = 100.0 * (r["volume_ml"] - s["voxel_volume_ml"]) / s["voxel_volume_ml"]
closed = r["watertight"] and r["components"] == 1
print("%-12s %10.2f %10.2f %+8.2f %9d %6s %6d %8s" % (sys.argv[1], r["volume_ml"], s["voxel_volume_ml"],
      diff, r["vertex_count"], "yes" if closed else "NO", r["euler_characteristic"], sys.argv[2]))
' "$name" "$seconds"
done

echo
echo "records: curl -s '$BASE_URL/v1/datasets/$DATASET/meshes?limit=20'"
