#!/usr/bin/env bash
# Train on a lent GPU machine that has PyTorch but no renderer and takes a few tens of MiB per
# transfer: the data travel as a lossless pack (tools/raindrop_tools/datapack.py), and three runs
# share the GPU for a fixed time, their step counts sized from the rate each reaches while the
# others run (scripts/gpu_step_rate.py).
#
#   scripts/gpu-train.sh pack [DIR]            here: data sets -> DIR (default out/gpu-carry)
#   scripts/gpu-train.sh train [DIR] [SECONDS] there: unpack, train for about SECONDS, and leave
#                                              $OUT/NAME.tar per run (its final checkpoint without
#                                              optimizer state, logs, resolved config) and
#                                              $OUT/train.log
#   here again: tar -xf NAME.tar -C tools/runs, then raindrop_tools.export --run tools/runs/NAME
#
# The runs (docs/RESULTS.md 4.26):
#   compact-real-coarse-gpu  tools/configs/compact-real-coarse-gpu.yaml, from models/compact: the
#                            control (same data and time at compact width; twice the crops on
#                            the CPU gained nothing held out, RESULTS 4.26)
#   paper-real-coarse-gpu    tools/configs/paper-real-coarse-gpu.yaml, from models/paper: the
#                            question (do the paper's widths fill large real drops better?)
#   paper-gpu                tools/configs/paper.yaml (the paper's settings), from scratch
# The data: of the training frames, 65 spread evenly, each with up to 4 paper-preset variants
# (data/train), 2 lens-cover and 2 windshield-day thin-lens variants and 3 Cityscapes lens-cover
# ones (merged into data/train-mix as scripts/results.sh does); and the real pairs' train split
# (never the test split). Built here by `scripts/results.sh data photoreal` beforehand.
set -euo pipefail
cd "$(dirname "$0")/.."
mode=${1:?usage: scripts/gpu-train.sh pack|train [DIR] [SECONDS]}
dir=${2:-out/gpu-carry}

if [[ $mode == pack ]]; then
  py=${RAINDROP_PYTHON:-.venv/bin/python}
  for d in data/train data/train-lens-cover data/train-windshield-day data/train-cs-lens data/real-pairs; do
    [[ -f $d/manifest.jsonl ]] || { echo "error: $d is missing (scripts/results.sh data photoreal makes it)" >&2; exit 1; }
  done
  # Only a folder this script packed before (its marker) is emptied: DIR may be any folder a
  # user names, and `pack data` once deleted the data sets themselves.
  if [[ -e $dir && ! -f $dir/.gpu-train-pack ]] && [[ -n $(ls -A "$dir" 2>/dev/null) || ! -d $dir ]]; then
    echo "error: '$dir' exists and was not made by 'scripts/gpu-train.sh pack' (no .gpu-train-pack in it); choose an empty or new folder" >&2
    exit 1
  fi
  rm -rf "$dir" && mkdir -p "$dir/wheels" && echo "made by scripts/gpu-train.sh pack; replaced by the next pack" >"$dir/.gpu-train-pack"
  PYTHONPATH=tools $py -m raindrop_tools.datapack pack "$dir/syn" data/train:4 data/train-lens-cover:2 \
    data/train-windshield-day:2 data/train-cs-lens:3 --frames 65
  PYTHONPATH=tools $py -m raindrop_tools.datapack pack "$dir/real" data/real-pairs --split train
  # the one package the trainer needs that the GPU machine's image lacks
  $py -m pip download -q --no-deps --only-binary=:all: -d "$dir/wheels" pytorch-msssim==1.0.0
  # What travels: the tracked files, untracked ones git does not ignore, and this folder.
  tree=$( { git ls-files -z; git ls-files -z -o --exclude-standard; } | du -cb --files0-from=- | tail -n 1 | cut -f1)
  pack=$(du -sb "$dir" | cut -f1)
  echo "travels: $((tree / 1048576)) MiB of working tree + $((pack / 1048576)) MiB here, limit 64 MiB"
  ((tree + pack < 63 * 1048576)) || { echo "error: over the transfer limit; pack fewer --frames" >&2; exit 1; }
  exit 0
fi

[[ $mode == train ]] || { echo "error: mode must be pack or train" >&2; exit 2; }
budget=${3:-360}
out=${OUT:-out/gpu-train}
mkdir -p "$out"
exec > >(tee "$out/train.log") 2>&1
python3 -m pip install -q --no-index --no-deps --no-compile --upgrade --target /tmp/site "$dir"/wheels/*.whl
export PYTHONPATH=/tmp/site:$PWD/tools PYTHONUNBUFFERED=1
nvidia-smi --query-gpu=name,memory.total,driver_version --format=csv,noheader || true
python3 -c 'import torch, cv2; print("torch", torch.__version__, "cuda", torch.version.cuda, "opencv", cv2.__version__)'
t0=$SECONDS
python3 -m raindrop_tools.datapack unpack "$dir/syn" data
python3 -m raindrop_tools.datapack unpack "$dir/real" data
python3 -m raindrop_tools.merge_datasets --out data/train-mix data/train-lens-cover data/train-windshield-day data/train-cs-lens
echo "data ready in $((SECONDS - t0)) s"

names=(compact-real-coarse-gpu paper-real-coarse-gpu paper-gpu)
configs=(tools/configs/compact-real-coarse-gpu.yaml tools/configs/paper-real-coarse-gpu.yaml tools/configs/paper.yaml)
inits=(models/compact models/paper "")
device=${GPU_TRAIN_DEVICE:-cuda}  # cpu: a local rehearsal of this script (a tiny budget)
probes=()
for i in 0 1 2; do python3 scripts/gpu_step_rate.py "${configs[$i]}" 15 "$device" >"/tmp/rate$i" & probes+=($!); done
wait "${probes[@]}"  # by pid: a plain wait would also wait for the tee above
runs=()
for i in 0 1 2; do
  rate=$(cat "/tmp/rate$i")
  # Stage 2 (RFN trained, RDN and 3RN forward only) costs about 0.7 of a stage-1 step and gets a
  # quarter of stage 1's steps; 0.8 leaves room for data loading and start-up.
  s1=$(python3 -c "n = int(0.8 * $rate * $budget / 1.175); print(max(8, n // 100 * 100 if n >= 1000 else n))")
  s2=$((s1 / 4))
  echo "${names[$i]}: $rate stage-1 steps/s while sharing -> $s1 + $s2 steps"
  init=()
  [[ -n ${inits[$i]} ]] && init=(--init-from "${inits[$i]}")
  timeout --signal=INT $((budget + 120)) python3 -m raindrop_tools.train --config "${configs[$i]}" \
    --out "runs/${names[$i]}" "${init[@]}" --device "$device" --no-progress \
    --set name="${names[$i]}" --set train.stage1_steps=$s1 --set train.stage2_steps=$s2 \
    --set data.workers=4 --set data.cache=true --set train.checkpoint_every=500 \
    >"runs-${names[$i]}.log" 2>&1 &
  runs+=($!)
done
status=0
for i in 0 1 2; do wait "${runs[$i]}" || { echo "${names[$i]}: exit $?"; status=1; }; tail -n 4 "runs-${names[$i]}.log"; done
echo "training done in $((SECONDS - t0)) s"
# The final checkpoints without optimizer state (the paper-width ones are 20 MiB with it).
python3 - "${names[@]}" <<'PY'
import glob, os, sys, torch
for run in [f"runs/{name}" for name in sys.argv[1:]]:  # this script's runs only
    ckpts = sorted(glob.glob(f"{run}/checkpoints/stage*_step*.pt"))
    for old in ckpts[:-1]:
        os.remove(old)
    if ckpts:
        state = torch.load(ckpts[-1], map_location="cpu", weights_only=False)
        state.pop("optimizers", None)
        state.pop("schedulers", None)
        torch.save(state, ckpts[-1])
        print(run, os.path.basename(ckpts[-1]), f"{os.path.getsize(ckpts[-1]) / 2**20:.1f} MiB")
PY
for i in 0 1 2; do
  cp "runs-${names[$i]}.log" "runs/${names[$i]}/train-output.log" 2>/dev/null || true
  [[ -d runs/${names[$i]} ]] && tar -cf "$out/${names[$i]}.tar" -C runs "${names[$i]}"
done
exit $status
