#!/usr/bin/env bash
# The figures of results/editor/README.md, in one run:
#  1. the criterion bench `editor` (per-frame basis vs memory floor vs full
#     solve on the Bunny and igea-537k; new selection vs deform's
#     precompute on the Bunny);
#  2. a scripted 300-frame drag of igea-537k in headless Chromium (20 %
#     fixed, a 2 % handle, as groups): the page's frame rate and the
#     server's per-frame compute, with screenshots.
# Needs ../shared/meshes (LSE_MESH_DIR), chromium and tests/browser's npm
# install. Usage: bash experiments/editor_figures.sh [OUT_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
out="${1:-results/editor}"
meshes="${LSE_MESH_DIR:-../shared/meshes}"
mkdir -p "$out"
cargo build --release --bin lse-deform
bin=target/release/lse-deform

# The paper's scene with groups: `scene` writes the fixed region at rest and
# the handle moved; the handle's rest targets are its vertices' positions.
scene_with_groups() {
    local mesh="$1" json="$2"
    "$bin" scene "$mesh" -o "$json.raw"
    python3 - "$mesh" "$json.raw" "$json" <<'EOF'
import gzip, json, sys
mesh, raw, out = sys.argv[1:]
opener = gzip.open if mesh.endswith('.gz') else open
p = []
with opener(mesh, 'rt') as f:
    for line in f:
        if line.startswith('v '):
            p.append([float(x) for x in line.split()[1:4]])
doc = json.load(open(raw))
cs = doc['constraints']
# The fixed constraints come first with their vertices' positions.
for c in cs:
    v = c['vertex']
    fixed = all(abs(a - b) <= 1e-12 * (1 + abs(b)) for a, b in zip(c['target'], p[v]))
    c['group'] = 'fixed' if fixed else 'handle 1'
    c['target'] = p[v]
json.dump(doc, open(out, 'w'))
EOF
}

LSE_MESH_DIR="$meshes" cargo bench --bench editor 2>&1 | tee "$out/bench.txt"

scene_with_groups "$meshes/igea-537k-subdiv.obj.gz" /tmp/igea-editor.json
(cd tests/browser && npm install --no-audit --no-fund >/dev/null)
"$bin" edit "$meshes/igea-537k-subdiv.obj.gz" --constraints /tmp/igea-editor.json --port 0 > /tmp/editor-igea.out 2>&1 &
server=$!
trap 'kill $server' EXIT
for _ in $(seq 600); do grep -q '^listening' /tmp/editor-igea.out && break; sleep 1; done
url=$(sed -n 's/^listening on //p' /tmp/editor-igea.out | head -1)
node tests/browser/drag_figure.mjs "$url" 300 "$out/igea-537k" | tee "$out/drag.json"
