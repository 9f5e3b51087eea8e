#!/usr/bin/env bash
# Rebuild the Freescale high-g reference outputs and check them against the committed files.
#
#   docs/scripts/fsl_highg/build_and_check.sh [PATH_TO_Open-Source-Sensor-Fusion_CHECKOUT]
#
# Without a path, clones https://github.com/memsindustrygroup/Open-Source-Sensor-Fusion into a
# temporary directory. Checks out commit b4a502a (build 422), copies the five fusion sources
# and their headers next to harness.c and the three stub headers, sets THISCOORDSYSTEM to NED
# in build.h (the only change), compiles with gcc -O2 (float32, x86-64), regenerates the
# inputs from imuhal's scenario (make_inputs.py), runs the harness on them and compares all
# four files byte for byte with tests/data/filters, then their SHA-256 with SHA256SUMS.
set -euo pipefail
HERE="$(cd "$(dirname "$0")" && pwd)"
ROOT="$(cd "$HERE/../../.." && pwd)"
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
SRC="${1:-}"
if [ -z "$SRC" ]; then
  git clone -q https://github.com/memsindustrygroup/Open-Source-Sensor-Fusion "$WORK/lib"
  SRC="$WORK/lib"
fi
BUILD="$WORK/build"
mkdir -p "$BUILD" "$WORK/out"
for f in fusion.c orientation.c matrix.c approximations.c magnetic.c build.h magnetic.h \
         matrix.h tasks.h orientation.h fusion.h approximations.h user_tasks.h include_all.h; do
  git -C "$SRC" show b4a502a:Sources/$f > "$BUILD/$f"
done
sed -i 's/^#define THISCOORDSYSTEM ANDROID/#define THISCOORDSYSTEM NED/' "$BUILD/build.h"
grep -q '^#define THISCOORDSYSTEM NED' "$BUILD/build.h"
cp "$HERE"/stubs/*.h "$HERE/harness.c" "$BUILD/"
gcc -O2 -w -o "$BUILD/harness" "$BUILD"/harness.c "$BUILD"/fusion.c "$BUILD"/orientation.c \
    "$BUILD"/matrix.c "$BUILD"/approximations.c "$BUILD"/magnetic.c -lm
PY="${PYTHON:-$ROOT/.venv/bin/python}"
"$PY" "$HERE/make_inputs.py" "$WORK/out"
"$BUILD/harness" "$WORK/out/fsl_highg_counts.csv" "$WORK/out/fsl_highg_9dof_gby_kalman.csv" \
    "$WORK/out/fsl_highg_6dof_gy_kalman.csv"
status=0
for f in fsl_highg_counts.csv fsl_highg_truth.csv fsl_highg_9dof_gby_kalman.csv \
         fsl_highg_6dof_gy_kalman.csv; do
  if cmp -s "$WORK/out/$f" "$ROOT/tests/data/filters/$f"; then
    echo "$f: identical to the committed file"
  else
    echo "$f: DIFFERS from the committed file"; status=1
  fi
done
(cd "$WORK/out" && sha256sum -c "$HERE/SHA256SUMS") || status=1
exit $status
