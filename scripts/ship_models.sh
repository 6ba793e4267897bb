#!/usr/bin/env bash
# Rebuild every shipped model in models/ from scratch, on CPU: datasets in data/, runs in runs/
# (both git-ignored). Each card in models/ records the held-out metrics and the command that
# measured them. Run from the repository root after `make demo` (or any install of the project).
# Trainings use one thread each, so that two of them (or a training and the test suite) share the
# machine's two cores without oversubscribing them.
#   scripts/ship_models.sh [strips16|strips16_small|strips16_spheres|strips5|fsr|thermal|thermal_wns|capacitive8 ...]   (default: all)
set -euo pipefail
cd "$(dirname "$0")/.."
TL=${TL:-.venv/bin/tactile-learn}
PY=${PY:-.venv/bin/python}

data() {  # scene, n, seed, folder
  $TL generate --scene "$1" --n "$2" --seed "$3" --out "data/$4" --workers 2 --quiet
}

ship() {  # run, model name, test folder
  $TL export "runs/$1" --out "models/$2.onnx" --test "data/$3" --overwrite
}

strips16() {  # the general model (the default): the whole shape library, 1-4 contacts, small network
  data strips16_mixed 400000 1 mixed-train; data strips16_mixed 5000 2 mixed-val; data strips16_mixed 5000 3 mixed-test
  data strips16_mixed 300000 4 mixed-train4
  $TL train --task strips --data data/mixed-train --val data/mixed-val --out runs/strips16_general --size small \
    --epochs 12 --threads 1 --val-limit 2000 --quiet
  # a second, shorter cycle on new frames at a lower rate (+0.002 r on validation, +0.003 on the ood suite)
  $TL train --task strips --data data/mixed-train4 --val data/mixed-val --out runs/strips16_tuned --size small \
    --epochs 6 --lr 1e-3 --threads 1 --val-limit 2000 --init runs/strips16_general --quiet
  # a third on single contacts emphasised (+0.003 on the ood suite, every family up but the smooth field)
  data strips16_mixed_single 300000 5 single-train; data strips16_mixed_single 5000 6 single-val
  $TL train --task strips --data data/single-train --val data/single-val --out runs/strips16_single --size small \
    --epochs 5 --lr 7e-4 --threads 1 --val-limit 2000 --init runs/strips16_tuned --quiet
  # a fourth on a mixture with the two-sphere set (40 % of the frames), then the average of its last
  # epoch and the third cycle's weights: two spheres r 0.911 -> 0.93, the ood suite as before
  data strips16 200000 1 strips16-train
  $TL train --task strips --data data/mixed-train4 data/single-train data/strips16-train data/strips16-train \
    --val data/mixed-val --out runs/strips16_mix --size small --epochs 4 --max-batches 800 --lr 7e-4 --threads 1 \
    --val-limit 2000 --init runs/strips16_single --quiet
  $PY scripts/average_weights.py runs/strips16_single runs/strips16_mix --last-epoch --out runs/strips16_soup
  # a fifth, longer cycle distilled from the two-sphere specialist: its maps are the targets of the
  # two-sphere frames (train --teacher), the other folders keep the truth; single contacts, smooth
  # fields and flat blocks get a folder of their own; then the average with the fourth cycle's
  # weights: two spheres r 0.933 -> 0.943, the ood suite as before (block at 30 degrees no longer
  # below the classical rules)
  data strips16_mixed_smooth 120000 11 smooth-train
  $TL train --task strips --data data/mixed-train4 data/single-train data/smooth-train data/strips16-train \
    data/strips16-train --val data/mixed-val --out runs/strips16_distill --size small --epochs 8 --max-batches 800 \
    --lr 5e-4 --threads 1 --val-limit 2000 --init runs/strips16_soup --teacher models/strips16_spheres.pt \
    --teacher-data data/strips16-train --quiet
  $PY scripts/average_weights.py runs/strips16_soup runs/strips16_distill --last-epoch --out runs/strips16_soup2
  # a sixth: the same data and teacher, the loss's per-frame (1 - r) term weighed up in three steps
  # (train --r-weight 3, 8, 20; r is what users read, the batch MSE weighs the heaviest frames), then
  # 0.4 of its weights with 0.6 of the fifth cycle's (more of it puts the block at 30 degrees below the
  # classical rules on an independent draw of the suite): two spheres r 0.943 -> 0.946, ood mean 0.818
  # -> 0.820, margin +0.046 -> +0.047, smooth field -0.005 -> -0.0046 (ood NRMSE 0.503 as before)
  set -- data/mixed-train4 data/single-train data/smooth-train data/strips16-train data/strips16-train
  local init=runs/strips16_soup2 seed=0 rw lr
  for rw in 3 8 20; do
    lr=$([ "$rw" = 3 ] && echo 4e-4 || echo 3e-4)
    $TL train --task strips --data "$@" --val data/mixed-val --out runs/strips16_r$rw --size small \
      --epochs $([ "$rw" = 3 ] && echo 6 || echo 5) --max-batches 800 --lr $lr --threads 1 --val-limit 2000 \
      --init $init --teacher models/strips16_spheres.pt --teacher-data data/strips16-train --r-weight $rw \
      --seed $seed --quiet
    init=runs/strips16_r$rw seed=$((seed + 1))
  done
  $PY scripts/average_weights.py runs/strips16_soup2 runs/strips16_r20 --weight 0.4 --out runs/strips16_soup3
  # a seventh: 24 crossing channels instead of 16 (size wide: the sixth cycle's network widened with
  # the same function, scripts/strips_grow.py; +17 us at batch 1), 5 x 800 batches at r-weight 20, then
  # 3 x 600 at r-weight 1 (the r term pushes the block at 30 degrees down), then 2 x 600 with the
  # smooth-field / flat-block folder twice, best epoch on validation: two spheres 0.946 -> 0.950, ood mean
  # 0.820 -> 0.821, margin +0.047 -> +0.048, smooth field -0.0046 -> -0.0035 (train --init keeps the
  # init's size)
  $PY scripts/strips_grow.py runs/strips16_soup3 --size wide --out runs/strips16_wide_init.pt
  $TL train --task strips --data "$@" --val data/mixed-val --out runs/strips16_wide --epochs 5 --max-batches 800 \
    --lr 4e-4 --threads 1 --val-limit 2000 --init runs/strips16_wide_init.pt --teacher models/strips16_spheres.pt \
    --teacher-data data/strips16-train --r-weight 20 --seed 3 --quiet
  $TL train --task strips --data "$@" --val data/mixed-val --out runs/strips16_wide2 --epochs 3 --max-batches 600 \
    --lr 2e-4 --threads 1 --val-limit 2000 --init runs/strips16_wide --teacher models/strips16_spheres.pt \
    --teacher-data data/strips16-train --seed 4 --quiet
  $TL train --task strips --data data/mixed-train4 data/smooth-train data/smooth-train data/strips16-train \
    --val data/mixed-val --out runs/strips16_wide3 --epochs 2 --max-batches 600 --lr 1.5e-4 --threads 1 \
    --val-limit 2000 --init runs/strips16_wide2 --teacher models/strips16_spheres.pt \
    --teacher-data data/strips16-train --seed 5 --quiet
  # an eighth: one consistency step through the forward model after the network (size wide_consistent,
  # tactile_learn/nets/strips_consistent.py: an ISRA step, no new weights, so strips_grow.py carries the
  # seventh cycle's weights over as they are), fine-tuned through the step: 3 x 600 batches on the
  # seventh's data, then 2 x 600 twice and 2 x 600 three times the smooth-field / flat-block folder at
  # lower rates, then the average with the seventh's weights (0.5): two spheres 0.950 -> 0.953, ood mean
  # 0.821 -> 0.823, margin +0.048 -> +0.051, smooth field -0.0035 -> -0.0030; +28 us at batch 1
  $PY scripts/strips_grow.py runs/strips16_wide3 --size wide_consistent --out runs/strips16_consistent_init.pt
  $TL train --task strips --data "$@" --val data/mixed-val --out runs/strips16_consistent --epochs 3 \
    --max-batches 600 --lr 2e-4 --threads 1 --val-limit 2000 --init runs/strips16_consistent_init.pt \
    --teacher models/strips16_spheres.pt --teacher-data data/strips16-train --seed 6 --quiet
  $TL train --task strips --data data/mixed-train4 data/smooth-train data/smooth-train data/strips16-train \
    --val data/mixed-val --out runs/strips16_consistent2 --epochs 2 --max-batches 600 --lr 1.5e-4 --threads 1 \
    --val-limit 2000 --init runs/strips16_consistent --teacher models/strips16_spheres.pt \
    --teacher-data data/strips16-train --seed 7 --quiet
  $TL train --task strips --data data/mixed-train4 data/smooth-train data/smooth-train data/smooth-train \
    data/strips16-train --val data/mixed-val --out runs/strips16_consistent3 --epochs 2 --max-batches 600 \
    --lr 1e-4 --threads 1 --val-limit 2000 --init runs/strips16_consistent2 --teacher models/strips16_spheres.pt \
    --teacher-data data/strips16-train --seed 8 --quiet
  $PY scripts/average_weights.py runs/strips16_consistent_init.pt runs/strips16_consistent3 --out runs/strips16_soup4
  # a ninth, on a GPU (train --device cuda; STRIPS_DEVICE=cpu runs the same recipe on the CPU, about
  # 67,000 batches of 512: some ten hours at one thread): the eighth's network on ~30 times the frames
  # of any CPU cycle, four runs each from the last (A: 8 x 423 then the mean of its
  # last 3 epochs; B: 8 x 2418 with twice the smooth-field folder; C: 14 x 2299 three times; D: 6 epochs
  # at a lower rate without the single-contact folder, its last epoch, averaged 0.85 / 0.15 with the
  # eighth): two spheres 0.953 -> 0.961, ood mean 0.823 -> 0.830, margin +0.051 -> +0.058, block 30 deg
  # above the rule on the suite, smooth field still below (-0.0027 against -0.0030). The GPU's arithmetic
  # differs from the CPU's: the recipe reproduces the model, not its bits.
  local device=${STRIPS_DEVICE:-cuda}
  gpu_train() {  # out, init, epochs, batches, lr, seed, data...
    local out=$1 init=$2 epochs=$3 batches=$4 lr=$5 seed=$6
    shift 6
    $TL train --task strips --data "$@" --val data/mixed-val --out "runs/$out" --epochs "$epochs" \
      --max-batches "$batches" --batch-size 512 --lr "$lr" --threads 8 --val-limit 2000 --init "$init" \
      --teacher models/strips16_spheres.pt --teacher-data data/strips16-train --seed "$seed" \
      --device "$device" --keep-epochs --quiet
  }
  gpu_train strips16_gpu1 runs/strips16_soup4 8 423 3e-4 22 "$@"
  $PY scripts/strips_soup.py runs/strips16_gpu1 --last 3 --out runs/strips16_gpu1_last3
  gpu_train strips16_gpu2 runs/strips16_gpu1_last3 8 3521 3e-4 23 data/mixed-train4 data/single-train \
    data/smooth-train data/smooth-train data/strips16-train data/strips16-train
  gpu_train strips16_gpu3 runs/strips16_gpu2 14 2299 2.5e-4 24 data/mixed-train4 data/single-train \
    data/smooth-train data/smooth-train data/smooth-train data/strips16-train data/strips16-train
  gpu_train strips16_gpu4 runs/strips16_gpu3 6 2725 1.2e-4 26 data/mixed-train4 data/smooth-train \
    data/smooth-train data/smooth-train data/strips16-train data/strips16-train
  # its last epoch averaged with the eighth's weights (0.85 / 0.15): the smooth field's deficit below the
  # eighth's on every draw, two spheres 0.962 -> 0.961
  $PY scripts/average_weights.py runs/strips16_soup4 runs/strips16_gpu4 --last-epoch --weight 0.85 \
    --out runs/strips16_gpu_final
  # a tenth, on the CPU at one thread (17 minutes): the sensor's physical range (synth/scenes/strips16_wide.toml:
  # 1-6 contacts, sizes up to the array's, 10 N; the ood and unseen suites' parameters held out), 160,000
  # frames of it three times beside the recipe's folders, 4 x 500 batches; then 3 x 500 with the mixture
  # weighed back towards strips16_mixed (its best epoch on validation, the last): unseen suite margin
  # +0.047 -> +0.051, families below the classical rules 3 -> 2 (the bottle cap -0.09 -> +0.002), two spheres
  # 0.961 -> 0.961; the cost: ood suite margin +0.057 -> +0.050 (the diagonal edge -0.07: a wider prior, more
  # shapes share its readings)
  data strips16_wide 160000 31 wide-train
  $TL train --task strips --data data/mixed-train4 data/wide-train data/wide-train data/wide-train data/smooth-train \
    data/strips16-train data/strips16-train --val data/mixed-val --out runs/strips16_widen --epochs 4 \
    --max-batches 500 --lr 1.5e-4 --threads 1 --val-limit 2000 --init runs/strips16_gpu_final \
    --teacher models/strips16_spheres.pt --teacher-data data/strips16-train --seed 40 --keep-epochs --quiet
  $TL train --task strips --data data/mixed-train4 data/mixed-train4 data/wide-train data/wide-train data/smooth-train \
    data/strips16-train data/strips16-train --val data/mixed-val --out runs/strips16_widen2 --epochs 3 \
    --max-batches 500 --lr 1e-4 --threads 1 --val-limit 2000 --init runs/strips16_widen/epoch-004.pt \
    --teacher models/strips16_spheres.pt --teacher-data data/strips16-train --seed 41 --keep-epochs --quiet
  # flag thresholds calibrated on the general distribution, not on the last cycle's
  $TL export runs/strips16_widen2 --out models/strips16.onnx --test data/mixed-test --calibration data/mixed-val --overwrite
  data strips16 4000 3 strips16-test; data strips16_twins 4000 3 strips16_twins-test
  $TL cards add --model models/strips16.onnx --name two_spheres --data data/strips16-test
  $TL cards add --model models/strips16.onnx --name strips16_twins --data data/strips16_twins-test
  $TL cards add --model models/strips16.onnx --name strips16_ood --suite strips16_ood
}

strips16_small() {  # the fast general model (issue 15): strips16 shrunk to size tiny, then fine-tuned
  data strips16_mixed 300000 4 mixed-train4; data strips16_mixed_single 300000 5 single-train
  data strips16 200000 1 strips16-train; data strips16_mixed 5000 2 mixed-val; data strips16_mixed 5000 3 mixed-test
  # the most used channels of the shipped default (8 of 16 crossing channels, one of two mixing blocks):
  # fine-tuning starts from a working inverse (3,200 batches from scratch reached ood 0.775, two spheres 0.899)
  # (the default as it was shipped with it: the fourth cycle's average, runs/strips16_soup of strips16())
  $PY scripts/strips_shrink.py runs/strips16_soup --size tiny --out runs/strips16_small_init.pt
  $TL train --task strips --data data/mixed-train4 data/single-train data/strips16-train data/strips16-train \
    --val data/mixed-val --out runs/strips16_small --size tiny --epochs 5 --max-batches 800 --lr 2e-3 --threads 1 \
    --val-limit 2000 --init runs/strips16_small_init.pt --quiet
  # then the mixture alone at a lower rate: 7 -> 3 families below the classical rules, two spheres 0.940 -> 0.921
  $TL train --task strips --data data/mixed-train4 data/single-train --val data/mixed-val --out runs/strips16_small2 \
    --size tiny --epochs 3 --max-batches 800 --lr 7e-4 --threads 1 --val-limit 2000 --init runs/strips16_small --quiet
  $TL export runs/strips16_small2 --out models/strips16_small.onnx --test data/mixed-test --calibration data/mixed-val --overwrite
  data strips16 4000 3 strips16-test; data strips16_twins 4000 3 strips16_twins-test
  $TL cards add --model models/strips16_small.onnx --name two_spheres --data data/strips16-test
  $TL cards add --model models/strips16_small.onnx --name strips16_twins --data data/strips16_twins-test
  $TL cards add --model models/strips16_small.onnx --name strips16_ood --suite strips16_ood
}

strips16_spheres() {  # the two-sphere specialist (first architecture): better on strips16 only, never the default
  data strips16 200000 1 strips16-train; data strips16 4000 2 strips16-val; data strips16 4000 3 strips16-test
  $TL train --task strips --data data/strips16-train --val data/strips16-val --out runs/strips16_large --size v1_large \
    --threads 1 --quiet
  ship strips16_large strips16_spheres strips16-test
  $TL cards add --model models/strips16_spheres.onnx --name strips16_ood --suite strips16_ood
}

strips5() {
  data strips5 100000 1 strips5-train; data strips5 4000 2 strips5-val; data strips5 4000 3 strips5-test
  $TL train --task strips --data data/strips5-train --val data/strips5-val --out runs/strips5 --size v1_small --epochs 10 \
    --threads 1 --quiet  # the first architecture, as shipped
  ship strips5 strips5 strips5-test
}

fsr() {
  data fsr6 400000 1 fsr-train; data fsr6 5000 2 fsr-val; data fsr6 20000 3 fsr-test
  $TL train --task fsr --data data/fsr-train --val data/fsr-val --out runs/fsr --size large --epochs 30 --threads 1 --quiet
  # export writes the lean graph (tactile_learn.nets.fsr_deploy: 26 nodes, not 36, the network's function);
  # the shipped fsr.onnx was re-exported so from fsr.pt: python scripts/reexport_model.py models/fsr.onnx
  ship fsr fsr fsr-test
}

thermal() {
  # 160,000 touches: twice the 80,000 first used, +4.6 points at 0.5 s of contact
  data thermal 160000 1 thermal-train160k; data thermal 1000 2 thermal-val; data thermal 300 11 thermal-test
  $TL train --task thermal --data data/thermal-train160k --val data/thermal-val --out runs/thermal_u160k --size small \
    --epochs 20 --threads 2 --quiet
  ship thermal_u160k thermal thermal-test
}

thermal_wns() {
  # 120,000 touches: with 30,000 the same network made 1.7x the errors at 0.5 s
  data thermal_wns 120000 1 thermal_wns-train120k; data thermal_wns 1000 2 thermal_wns-val
  data thermal_wns 300 12 thermal_wns-test
  $TL train --task thermal --data data/thermal_wns-train120k --val data/thermal_wns-val --out runs/thermal_wns_u \
    --epochs 20 --threads 1 --quiet
  ship thermal_wns_u thermal_wns thermal_wns-test
}

capacitive8() {
  # the device's calibration comes first: it is part of the scenes the model is trained and run on.
  # A probe rig presses every cell of the device (seed 1); every scene of that device gets the table.
  data capacitive8_rig 192 7 capacitive8-rig
  for scene in capacitive8 capacitive8_frames fingertip; do
    $TL calibrate --task capacitive --data data/capacitive8-rig --scene "$scene" --out "synth/scenes/$scene.toml"
  done
  data capacitive8 10000 1 capacitive8-train; data capacitive8 250 2 capacitive8-val; data capacitive8 1000 3 capacitive8-test
  $TL train --task capacitive --data data/capacitive8-train --val data/capacitive8-val --out runs/capacitive8 \
    --epochs 10 --batch-size 64 --threads 1 --quiet
  ship capacitive8 capacitive8 capacitive8-test
}

mkdir -p data runs models
for target in "${@:-strips16 strips16_small strips16_spheres strips5 fsr thermal thermal_wns capacitive8}"; do
  for t in $target; do
    echo "=== $t"
    "$t"
  done
done
