#!/bin/bash
# Runs `cfl suite` over every mesh file of a directory tree that cfl can read: a check on models nobody
# tuned the library on (by default Debian's assimp-testmodels, 3D files in some 40 formats, mostly from
# other projects' test suites).
#
# usage: bench/sweep_models.sh [MODELS_DIR] [OUT_DIR] [cfl suite options...]
#   MODELS_DIR  default /usr/share/assimp/models (apt-get install assimp-testmodels)
#   OUT_DIR     default /tmp/cfl_sweep; gets manifest.txt, refused.txt and links/
#   env CFL     the cfl tool (default: build/bench/cfl next to this script's repository)
#   env MIN_TRIANGLES, MAX_TRIANGLES   the meshes kept (default 200 and 150000)
#   env PAIRS=1  also one case per kept mesh against another: with the meshes in order of size, mesh i
#                against mesh i + n/2 (mod n), pairs of different sizes. Models drawn in different units may
#                not reach every band (the poses put B's box center on rays from A's): the table shows "-"
#                there and a note says why.
#   Suite options default to --queries 6 --repeats 2 --clock cpu --bands 0,0.005,0.02,0.1,0.5.
#
# Every file is first read with `cfl info`: those it refuses are listed with its reason in
# OUT_DIR/refused.txt (a texture, a file with no triangle, a malformed one). Of the rest, one file per
# distinct mesh (same triangle and vertex counts and bounding box: the same model exported to several
# formats) within the size range becomes a case, A against itself (and with PAIRS=1 one more against another
# mesh). The suite then prints its table, worst case first, and exits 1 if any CFL distance differs from the
# reference by more than 1e-9 of the diagonal.
set -euo pipefail
export LC_ALL=C  # the order of the files, so which of a mesh's copies is kept, does not depend on the locale

here=$(cd "$(dirname "$0")/.." && pwd)
models=${1:-/usr/share/assimp/models}
out=${2:-/tmp/cfl_sweep}
shift $(( $# < 2 ? $# : 2 ))
cfl=${CFL:-$here/build/bench/cfl}
min=${MIN_TRIANGLES:-200}
max=${MAX_TRIANGLES:-150000}
if [ ! -d "$models" ]; then
  echo "sweep_models.sh: $models: no such directory (Debian: apt-get install assimp-testmodels)" >&2
  exit 2
fi
if [ ! -x "$cfl" ]; then
  echo "sweep_models.sh: $cfl: no cfl tool (build it: cmake --build build), or set CFL" >&2
  exit 2
fi
suite_options=("$@")
if [ ${#suite_options[@]} -eq 0 ]; then
  suite_options=(--queries 6 --repeats 2 --clock cpu --bands 0,0.005,0.02,0.1,0.5)
fi

rm -rf "$out"
mkdir -p "$out/links"
: > "$out/manifest.txt"
: > "$out/refused.txt"
: > "$out/sizes.txt"
declare -A seen
kept=0 refused=0 duplicates=0 outside=0 links=0
while IFS= read -r -d '' file; do
  status=0
  info=$(timeout 120 "$cfl" info "$file" 2>&1) || status=$?
  if [ "$status" -ne 0 ]; then
    reason=$(printf '%s' "$info" | grep -v '^building' | tail -1 || true)
    [ "$status" -eq 124 ] && reason="cfl info did not finish within 120 s"
    printf '%s: %s\n' "$file" "${reason:-cfl info failed with status $status}" >> "$out/refused.txt"
    refused=$((refused + 1))
    continue
  fi
  triangles=$(printf '%s\n' "$info" | awk '/^triangles:/ {print $2}')
  key=$(printf '%s\n' "$info" | grep -E '^(triangles|vertices|bounding box):' | tr -s ' ' | tr '\n' ' ')
  if [ -n "${seen[$key]:-}" ]; then duplicates=$((duplicates + 1)); continue; fi
  seen[$key]=1
  if [ "$triangles" -lt "$min" ] || [ "$triangles" -gt "$max" ]; then outside=$((outside + 1)); continue; fi
  # The manifest splits on white space: a path holding some goes through a link to its directory, so that
  # files it refers to (a glTF's buffers, an OBJ's materials) are still found beside it.
  path=$file
  if [[ "$file" =~ [[:space:]] ]]; then
    links=$((links + 1))
    ln -s "$(dirname "$file")" "$out/links/$links"
    path="$out/links/$links/$(basename "$file")"
    if [[ "$path" =~ [[:space:]] ]]; then
      ln -s "$file" "$out/links/$links.$(basename "$file" | sed 's/.*\.//')"
      path="$out/links/$links.$(basename "$file" | sed 's/.*\.//')"
    fi
  fi
  name=$(printf '%s' "${file#"$models"/}" | tr -c 'A-Za-z0-9_\n' '_')
  printf '%s %s\n' "$name" "$path" >> "$out/manifest.txt"
  printf '%s %s %s\n' "$triangles" "$name" "$path" >> "$out/sizes.txt"
  kept=$((kept + 1))
done < <(find "$models" -type f -print0 | sort -z)

if [ "${PAIRS:-0}" = 1 ] && [ "$kept" -gt 1 ]; then
  sort -n -k1,1 -k2,2 "$out/sizes.txt" | awk '{ name[NR] = $2; path[NR] = $3 }
    END { for (i = 1; i <= NR; ++i) { j = (i - 1 + int(NR / 2)) % NR + 1; print name[i] "_vs_" name[j], path[i], path[j] } }' \
    >> "$out/manifest.txt"
fi

echo "sweep_models.sh: $models: $kept meshes of $min to $max triangles; $duplicates files repeat a mesh already" \
     "kept, $outside lie outside that range, $refused are refused by cfl (reasons in $out/refused.txt)"
exec "$cfl" suite "$out" "${suite_options[@]}"
