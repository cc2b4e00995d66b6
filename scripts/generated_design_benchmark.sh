#!/usr/bin/env bash
# The per-camera stabiliser model on generated stabiliser designs, in the paper's image metric:
# for every design seed given, the README's per-camera protocol, rendered as any module is
# (docs/stabiliser_model.md, "Benchmark: stabiliser modules and cameras"):
#   1. renders 6 + 1 training recordings of 5 s (RE camera, seeds 3000-3006; 3006 held out for the
#      candidate choice) and one evaluation sequence per category (RE, LT, LL, MF, seed 4000,
#      70 pairs each), with OIS driven by the design (`ois: {design_seed: N}`);
#   2. trains the per-camera model from the images (train_stabiliser, ground truth cached);
#   3. runs `evaluate` with the non-OIS twins (rendered once: without OIS a design changes
#      nothing), the shipped generic stabiliser model, the per-camera model and the design's
#      oracle (its own controller on the camera's gyro);
#   4. prints one table row per design: Avg geometry distance capped / uncapped and the gap to the
#      twin closed, capped / uncapped, of each row.
#
#   generated_design_benchmark.sh OUT_DIR SEED [SEED ...]
#       e.g. $(seq 0 5 195) for the 40 first designs of the held-out split (seed % 5 == 0)
# Re-running skips what exists (bags, models, reports), so an interrupted run resumes. OUT_DIR/
# table.md collects the rows. One design takes about 3 minutes on one core.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# shellcheck disable=SC1091
source "$repo/scripts/ros_env.sh"
[ $# -ge 2 ] || { echo "usage: generated_design_benchmark.sh OUT_DIR SEED [SEED ...]" >&2; exit 2; }
out="$1"
shift
config="$repo/config/simulator"
mkdir -p "$out/twins" "$out/cache"
# The RE camera's readout (config/simulator/RE.yaml) is the package's gyro flow default.
cp "$repo/config/gyro_flow.yaml" "$out/gyro_flow.yaml"

render() {  # $1 camera config, $2 overlay, $3 seed, $4 duration, $5 on|off, $6 out
  [ -s "$6" ] && return 0
  rosrun deep_ois simulate --config "$1" --overlay "$2" --seed "$3" --duration "$4" --ois "$5" \
    --out "$6.tmp" --quiet --compression lz4 >"$6.log" 2>&1 || { cat "$6.log" >&2; return 1; }
  mv "$6.tmp" "$6"
}
# The gap closed "capped / uncapped" of a report's row, and its Avg in table 1 (capped) or 2.
gap() { grep -m1 -F -- "- $2: " "$1" | sed 's/.*: //; s/ % capped, / \/ /; s/ % uncapped/ %/'; }
avg() {
  awk -F'|' -v row="$2" -v want="$3" '
    /^\| method \|/ { table++ }
    table == want && $2 == " " row " " { gsub(/ /, "", $(NF-1)); print $(NF-1); exit }' "$1"
}

table="$out/table.md"
if [ ! -s "$table" ]; then
  {
    printf '| design | class | twin | OIS gyro | generic model | per-camera | oracle | gap closed: generic | per-camera | oracle | kept candidate |\n'
    printf '|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---|\n'
  } >"$table"
fi
status=0
for seed in "$@"; do
  dir="$out/design_$seed"
  mkdir -p "$dir/train" "$dir/eval"
  overlay="$dir/overlay.yaml"
  printf 'ois:\n  design_seed: %s\n' "$seed" >"$overlay"
  started=$(date +%s)
  for s in 3000 3001 3002 3003 3004 3005 3006; do
    render "$config/RE.yaml" "$overlay" "$s" 5.0 on "$dir/train/RE_$s.bag"
  done
  for cat in RE LT LL MF; do
    render "$config/$cat.yaml" "$overlay" 4000 2.3334 on "$dir/eval/${cat}_4000.bag"
    render "$config/$cat.yaml" "$overlay" 4000 2.3334 off "$out/twins/${cat}_4000_nonois.bag"
    ln -sf "$out/twins/${cat}_4000_nonois.bag" "$dir/eval/${cat}_4000_nonois.bag"
  done
  class=$(sed -n 's/.*generated design [0-9]* (\([^,]*\),.*/\1/p' "$dir/train/RE_3000.bag.log")
  train=("$dir"/train/RE_300[0-5].bag)
  model="$dir/model.yaml"
  if [ ! -s "$model" ]; then
    # Exit status 3: the model was written with warnings (implausible parameters): kept and scored
    # (leaving the design out would flatter the figures), the warning said in the table.
    rc=0
    rosrun deep_ois train_stabiliser --bags "${train[@]}" --held-out "$dir/train/RE_3006.bag" \
      --gyro-config "$out/gyro_flow.yaml" --cache "$out/cache/design_$seed" --out "$model" \
      --no-progress >"$dir/train.log" 2>&1 || rc=$?
    if [ "$rc" -ne 0 ] && ! { [ "$rc" -eq 3 ] && [ -s "$model" ]; }; then
      rm -f "$model"
      echo "generated_design_benchmark: design $seed: train_stabiliser failed, see $dir/train.log" >&2
      status=1
      continue
    fi
  fi
  report="$dir/report/evaluation.md"
  if [ ! -s "$report" ]; then
    rosrun deep_ois evaluate --bags "$dir"/eval/*.bag --gyro-config "$out/gyro_flow.yaml" --no-model \
      --no-image-baselines --no-ground-truth --ghost-pairs 0 --out "$dir/report" \
      --stabiliser "$repo/models/stabiliser_generic.yaml" "$model" \
      --oracle "$overlay" >"$dir/evaluate.log" 2>&1 || {
      echo "generated_design_benchmark: design $seed: evaluate failed, see $dir/evaluate.log" >&2
      status=1
      continue
    }
  fi
  log="$dir/evaluate.log"
  both() { echo "$(avg "$log" "$1" 1) / $(avg "$log" "$1" 2)"; }
  generic="stabiliser model, stabiliser_generic.yaml"
  camera="stabiliser model, model.yaml"
  oracle="oracle, overlay.yaml controller on the camera gyro"
  kept=$(awk -F'|' '$5 ~ /kept/ { gsub(/^ +| +$/, "", $2); print $2; exit }' "$dir/train.log")
  grep -q "^WARNING: implausible" "$dir/train.log" && kept="$kept (warning: model implausible)"
  row="| $seed | $class | $(both "gyro, non-OIS camera") | $(both "gyro, OIS camera (uncompensated)") | $(both "$generic") | $(both "$camera") | $(both "$oracle") | $(gap "$log" "$generic") | $(gap "$log" "$camera") | $(gap "$log" "$oracle") | $kept |"
  grep -q "^| $seed |" "$table" || echo "$row" >>"$table"
  echo "design $seed ($class): $(( $(date +%s) - started )) s: $row"
done
# Per class and over all rows of the table: the median gap closed (capped / uncapped) of each row
# and how many designs meet the issue's bar (>= 95 % capped, or within 3 points of the oracle).
/usr/bin/python3 - "$table" <<'PY'
import collections, statistics, sys
rows = [l.split("|")[1:-1] for l in open(sys.argv[1]) if l.startswith("| ") and l[2].isdigit()]
def pair(cell):
    a, b = cell.replace("%", "").split("/")
    return float(a), float(b)
groups = collections.defaultdict(list)
for r in rows:
    r = [c.strip() for c in r]
    g = {k: pair(r[i]) for k, i in (("generic", 7), ("camera", 8), ("oracle", 9))}
    groups[r[1]].append(g)
    groups["all"].append(g)
print("| class | designs | generic | per-camera | oracle | per-camera meets the bar | median points below the oracle |")
print("|---|---:|---:|---:|---:|---:|---:|")
med = lambda gs, k, j: statistics.median(g[k][j] for g in gs)
bar = lambda g, k: g[k][0] >= 95.0 or g[k][0] >= g["oracle"][0] - 3.0
for name in sorted(groups, key=lambda n: (n == "all", n)):
    gs = groups[name]
    cells = ["%.1f / %.1f %%" % (med(gs, k, 0), med(gs, k, 1)) for k in ("generic", "camera", "oracle")]
    below = statistics.median(g["oracle"][0] - g["camera"][0] for g in gs)
    print("| %s | %d | %s | %d | %.1f |" % (name, len(gs), " | ".join(cells), sum(bar(g, "camera") for g in gs), below))
PY
exit $status
