#!/usr/bin/env bash
# Setup step: the learned VLA / VTLA-real / VTLA-pred policies of both tasks in
# .build/models/learned, and the demonstrations they are trained on as LeRobot v3.0 datasets.
#   1. `unitac-lab demos --mode M` records the scripted expert on the TRAINING objects of each task
#      (seeds 1,2,3 x 20 trials) deciding from what mode M observes: vtla_real's demonstrations
#      probe the cup before the squeeze and grasp the fabric the live comparison names; vla's
#      grasp the fabric the camera's roughness guesses name, with no probe. vtla_pred observes
#      nothing more that the probe or the choice could use (its predicted latent is drawn
#      without the object), so its demonstrations are vla's (the same draws, the same commands:
#      recorded once, the dataset copied). The vtla_real and vtla_pred scenes' tactile stages
#      watch every trial, so every tick carries every mode's observations; each vtla_real fabric
#      demonstration must hold the comparison at its decision, and the decisions must name both
#      fabrics (checked here on the recorded demos.json);
#   2. python/unitac_tools/lerobot_dataset.py lays them out in .build/models/learned/datasets/<task>/<mode>
#      (LeRobot v3.0);
#   3. python/unitac_tools/train_policy.py trains the 3 modes x 2 tasks once per training seed (0, 1, 2), each
#      mode on its own demonstrations, into .build/models/learned/seed<k>/<task>_<mode> (ONNX +
#      manifest.json) and checks ONNX Runtime against its numpy forward.
# UNITAC_DAGGER=1 (opt-in, not a setup step: its retrained policies did worse in closed loop,
# crates/policy/README.md "DAgger") adds one round of DAgger per training seed: each first-round
# policy drives the world on the training objects (`unitac-lab demos --drive`, draw seed 4,
# DAGGER_TRIALS trials), every tick labelled with that mode's expert's command there, laid out as LeRobot
# datasets (.build/models/learned/dagger/seed<k>/<task>_<mode>), and python/unitac_tools/train_policy.py
# --dagger trains each seed's policies again on the demonstrations plus its own DAgger states.
# Needs the stages run and touch of scripts/setup.sh (the reference and touch bundles the scenes
# load) and python (pyarrow); `scripts/setup.sh learned` runs it with them.
# Skipped when its inputs did not change (a stamp of them in .build/models/learned/.stamp); when
# they did, the demonstrations are recorded again and the policies trained only if the datasets
# or the trainer differ from those they were trained on (scripts/stamps.sh).
# UNITAC_LEARNED puts it elsewhere (the policy tests read it too).
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$ROOT"
# The ONNX Runtime library and the model paths the scenes name.
source scripts/env.sh
VENV="${UNITAC_VENV:-$ROOT/.venv}"
MODELS="$ROOT/.build/models"
export UNITAC_MODELS="${UNITAC_MODELS:-$MODELS}"
OUT="${UNITAC_LEARNED:-$MODELS/learned}"
TASKS=(cup_deformation fabric_selection)
SEEDS=(0 1 2)
MODES=(vla vtla_real vtla_pred)
DAGGER="${UNITAC_DAGGER:-0}"
DAGGER_SEED=4
DAGGER_TRIALS=4
log() { printf '[setup] %s\n' "$*" >&2; }
# shellcheck source=scripts/stamps.sh
source scripts/stamps.sh

inputs=(scripts/learned_policies.sh scripts/stamps.sh python/unitac_tools/lerobot_dataset.py python/unitac_tools/train_policy.py
  python/unitac_tools/generate_reference.py python/unitac_tools/schema.py schema/policy.json Cargo.lock crates/lab/src/demos.rs crates/lab/src/main.rs
  launch/scenes/*_learned_*.yaml
  launch/scenes/cup_deformation_vtla_real.yaml launch/scenes/cup_deformation_vtla_pred.yaml
  launch/scenes/fabric_selection_vtla_real.yaml launch/scenes/fabric_selection_vtla_pred.yaml
  $(find crates/sim/src crates/contact/src crates/core/src crates/infer/src crates/trials/src crates/pipeline/src crates/policy/src -name '*.rs' | sort))
key="$( (cat "${inputs[@]}" "$MODELS/reference/manifest.json" "$MODELS/touch/manifest.json" 2>/dev/null; echo "dagger $DAGGER") | sha256sum | cut -d' ' -f1)"
if [ "$(cat "$OUT/.stamp" 2>/dev/null)" = "$key" ] \
  && [ -f "$OUT/seed${SEEDS[-1]}/${TASKS[-1]}_vtla_pred/manifest.json" ]; then
  exit 0
fi
log "learned policies: demonstrations of both tasks on training objects (~13 min), LeRobot datasets, training (~5 min)"
start=$SECONDS
cargo build --release --locked -q -p unitac-lab
rm -rf "$OUT.tmp"
mkdir -p "$OUT.tmp"
# Every vtla_real fabric demonstration decided once the comparison was in its observation, and
# the demonstrations of each mode decided for both fabrics.
check_decisions() {
  "$VENV/bin/python" - "$@" <<'PY'
import json, sys
path, mode = sys.argv[1], sys.argv[2]
demos = json.load(open(path))["demos"]
chosen = set()
for d in demos:
    where = f"{path}: seed {d['seed']} trial {d['trial']}"
    if not d["chosen"]:
        sys.exit(f"{where}: no decision")
    chosen.add(d["chosen"])
    at = next(t for t in d["ticks"] if t["t_s"] >= d["decided_s"])
    if mode == "vtla_real" and sum(at["comparison"][:3]) != 1.0:
        sys.exit(f"{where}: decided at {d['decided_s']:.3f} s without the comparison")
if len(chosen) < 2:
    sys.exit(f"{path}: every decision was {sorted(chosen)}")
print(f"[setup] {mode} fabric decisions: " + ", ".join(
    f"{c} {sum(d['chosen'] == c for d in demos)}" for c in sorted(chosen)), file=sys.stderr)
PY
}
# record TASK MODE: one mode's demonstrations of one task, checked, laid out as a LeRobot dataset.
record() {
  local task="$1" mode="$2" d="$OUT.tmp/demos/$1/$2"
  target/release/unitac-lab demos --scene "${task}_vtla_real,${task}_vtla_pred" --mode "$mode" \
    --split train --seeds 1,2,3 --trials 20 --out "$d" >&2
  if [ "$task" = fabric_selection ]; then check_decisions "$d/demos.json" "$mode"; fi
  "$VENV/bin/python" -m unitac_tools.lerobot_dataset --demos "$d/demos.json" \
    --out "$OUT.tmp/datasets/$task/$mode" >&2
}
sets=()
for task in "${TASKS[@]}"; do
  # The recorder runs on one core: a task's two modes side by side (each writes its own files).
  pids=()
  for mode in vtla_real vla; do
    record "$task" "$mode" &
    pids+=($!)
  done
  for p in "${pids[@]}"; do wait "$p"; done
  cp -r "$OUT.tmp/datasets/$task/vla" "$OUT.tmp/datasets/$task/vtla_pred"
  sets+=(--dataset "$OUT.tmp/datasets/$task")
done
rm -rf "$OUT.tmp/demos"
log "learned policies: demonstrations and datasets in $((SECONDS - start)) s"
# The policies depend on the datasets, the trainer and the training seeds; DAgger's states also on
# the closed loop, so with DAgger they are always trained again.
data_key="$( (content_key "$OUT.tmp/datasets" python/unitac_tools/train_policy.py python/unitac_tools/generate_reference.py \
  python/unitac_tools/schema.py schema/policy.json "$VENV/.unitac-stamp"; echo "seeds ${SEEDS[*]} dagger $DAGGER") \
  | sha256sum | cut -d' ' -f1)"
if [ "$DAGGER" = 0 ] && stands "$OUT" "$data_key" \
  && [ -f "$OUT/seed${SEEDS[-1]}/${TASKS[-1]}_vtla_pred/manifest.json" ]; then
  log "learned policies: the datasets are byte-identical to the policies': they stand ($((SECONDS - start)) s)"
  rm -rf "$OUT/datasets"
  mv "$OUT.tmp/datasets" "$OUT/datasets"
  rm -rf "$OUT.tmp"
  echo "$key" >"$OUT/.stamp"
  exit 0
fi
first="$OUT.tmp"
[ "$DAGGER" = 1 ] && first="$OUT.tmp/round0"
for seed in "${SEEDS[@]}"; do
  "$VENV/bin/python" -m unitac_tools.train_policy "${sets[@]}" --seed "$seed" --out "$first/seed$seed" >/dev/null
done
for seed in "${SEEDS[@]}"; do
  [ "$DAGGER" = 1 ] || break
  [ "$seed" = "${SEEDS[0]}" ] && log "learned policies: first round $((SECONDS - start)) s; DAgger"
  for task in "${TASKS[@]}"; do
    for mode in "${MODES[@]}"; do
      d="$OUT.tmp/dagger/seed$seed/${task}_$mode"
      target/release/unitac-lab demos --scene "${task}_vtla_real,${task}_vtla_pred" --mode "$mode" \
        --split train --seeds "$DAGGER_SEED" --trials "$DAGGER_TRIALS" --drive "${task}_learned_$mode" \
        --drive-model "$OUT.tmp/round0/seed$seed/${task}_$mode/manifest.json" --out "$d.demos" >&2
      "$VENV/bin/python" -m unitac_tools.lerobot_dataset --demos "$d.demos/demos.json" --out "$d" >&2
      rm -rf "$d.demos"
    done
  done
  "$VENV/bin/python" -m unitac_tools.train_policy "${sets[@]}" --seed "$seed" \
    --dagger "$OUT.tmp/dagger/seed$seed" --out "$OUT.tmp/seed$seed" >/dev/null
done
rm -rf "$OUT.tmp/round0"
"$VENV/bin/python" -m unitac_tools.train_policy --check-onnx "$OUT.tmp/seed0" "${sets[@]}" >/dev/null
echo "$data_key" >"$OUT.tmp/.data-key"
rm -rf "$OUT"
mv "$OUT.tmp" "$OUT"
echo "$key" >"$OUT/.stamp"
log "learned policies: $((SECONDS - start)) s"
