#!/usr/bin/env bash
# Every exact formulation on every real mesh and Laplacian against the
# independent augmented-system reference (augmented_lse.py), with and without
# refinement. One line per solve: estimate, steps, warning count, the true
# error (dX, over the bounding-box diagonal) and the energy difference (dE).
#
# Usage (from the repository root, after `cargo build --release`):
#   PY=path/to/python-with-numpy-scipy experiments/reference/all_meshes.sh ../shared/meshes WORKDIR
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
B=${B:-$here/../../target/release/lse-deform}
PY=${PY:-python3}
meshes=$1
work=$2
mkdir -p "$work"
cd "$work"
for f in "$meshes"/*.obj; do
    n=$(basename "$f" .obj)
    case $n in igea-134k) continue ;; esac # the SciPy reference needs too long for it
    "$B" scene "$f" -o "$n.json" >/dev/null 2>&1
    for lap in uniform cotan cotan-symmetric intrinsic-delaunay; do
        "$B" export-system "$f" -c "$n.json" --laplacian $lap -o "sys_${n}_$lap" >/dev/null 2>&1
        "$PY" "$here/augmented_lse.py" "sys_${n}_$lap" "ref_${n}_$lap.mtx" >/dev/null
        for m in nullspace-qr kkt eliminate; do
            for r in auto off; do
                warned=$("$B" deform "$f" -c "$n.json" --laplacian $lap --method $m --refine $r \
                    -o o.obj --report o.json 2>&1 | grep -c "forward error .* exceeds" || true)
                est=$("$PY" -c "import json;r=json.load(open('o.json'));print('%.1e %d' % (r['forward_error_estimate'], r['refinement']['steps']))")
                chk=$("$PY" "$here/check_against.py" "sys_${n}_$lap" "ref_${n}_$lap.mtx" o.obj o.json)
                echo "$n $lap $m refine=$r est=$est warned=$warned $chk"
            done
        done
    done
done
