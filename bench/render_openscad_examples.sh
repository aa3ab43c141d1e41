#!/bin/bash
# Renders the example models that Debian's OpenSCAD ships (CSG parts: cylinders and spheres cut from boxes,
# extrusions, text, a candle stand, gears of the old examples) to STL, for bench/sweep_models.sh: CAD parts
# as a CAD program tessellates them, with the long thin triangles of its cylinders and fillets, which nobody
# tuned cfl on.
#
# usage: bench/render_openscad_examples.sh [OUT_DIR]
#   OUT_DIR  default /tmp/cfl_openscad; gets one STL per example that renders to a solid, named
#            <folder>_<example>.stl, and logs/ with OpenSCAD's output for each
#   env OPENSCAD_EXAMPLES  default /usr/share/openscad/examples (apt-get install openscad)
#   env OPENSCAD_TIMEOUT   seconds per example (default 300)
#
# Examples that are not a 3D object (2D drawings, echo and assert demonstrations) or do not render within
# the timeout are listed with OpenSCAD's last line and skipped. Then:
#   bench/sweep_models.sh OUT_DIR /tmp/cfl_sweep_openscad --queries 20 --repeats 3 --clock cpu \
#       --bands 0,0.005,0.02,0.1,0.5,1
set -euo pipefail
export LC_ALL=C  # the examples' order, so the log's, does not depend on the locale

out=${1:-/tmp/cfl_openscad}
examples=${OPENSCAD_EXAMPLES:-/usr/share/openscad/examples}
limit=${OPENSCAD_TIMEOUT:-300}
if ! command -v openscad > /dev/null; then
  echo "render_openscad_examples.sh: no openscad (Debian: apt-get install openscad)" >&2
  exit 2
fi
if [ ! -d "$examples" ]; then
  echo "render_openscad_examples.sh: $examples: no such directory" >&2
  exit 2
fi

mkdir -p "$out/logs"
out=$(cd "$out" && pwd)  # the renders run from each example's folder
rendered=0 skipped=0
while IFS= read -r -d '' scad; do
  name=$(basename "$(dirname "$scad")")_$(basename "$scad" .scad)
  name=$(printf '%s' "$name" | tr -c 'A-Za-z0-9_\n' '_')
  log="$out/logs/$name.log"
  status=0
  # OpenSCAD resolves use<> and import() relative to the example, so it runs from the example's folder.
  (cd "$(dirname "$scad")" && timeout "$limit" openscad -o "$out/$name.stl" "$scad") > "$log" 2>&1 || status=$?
  if [ "$status" -eq 0 ] && [ -s "$out/$name.stl" ]; then
    rendered=$((rendered + 1))
  else
    rm -f "$out/$name.stl"
    reason=$(grep -v '^ *$' "$log" | tail -1 || true)
    [ "$status" -eq 124 ] && reason="did not render within $limit s"
    echo "skipped $scad: ${reason:-openscad exited with status $status}"
    skipped=$((skipped + 1))
  fi
done < <(find "$examples" -name '*.scad' -print0 | sort -z)
echo "render_openscad_examples.sh: $rendered examples rendered to $out, $skipped skipped"
