#!/usr/bin/env bash
# Regenerates every figure of docs/RESULTS.md into out/results/ (run after scripts/setup.sh
# and scripts/setup-tools.sh; needs a folder of real photographs, $RAINDROP_SHARED_DATA
# (default ../shared/data), for the real frames). Sections can be chosen:
# scripts/results.sh data render stats eval remove tradeoffs sheets photoreal scale flatroad largedrops coarsetrain
# largedropmodels sensor mirroraverage highlights multiscale veil papermodels outline trails photos windshield
# windshield-followup longer growth sharpness coalesce surround largewidth largedrops-all windshield2
# errorsplit withoutvnni graphrewrites jitter windshieldscale router routed int8router droplets realismcontrol
# droplets2 infocus realismbar windshieldday fillarea finedrops lanes glassplate platerecon aperturelanes headrouter int8head headthreshold dilation coarsescales mainthreshold
# rim headtext headnight headdiscs workers int8default sampledlayers dry wetgate evalprogram photostally largedetail
#
# Sections measured before docs/RESULTS.md 4.44 run compact-windshield's detector (and the routed
# default) with --surround-fill-area 150, the area they had then, so that they reproduce.
# Sections measured before 4.54 ran without the fill's growth into rims (now on by default); run
# now, the default's rows there may differ by the few hundredths of a dB 4.54 measured (pass
# --surround-fill-rim 0 to raindrop-remove for the figures as they were).
# Sections measured before 4.60 ran the float default where they name no model; since 4.60 a CPU
# with VNNI loads the default's int8 copy there (models/DEFAULT's vnni line), so on such a CPU
# their default's rows are the int8 copy's (0.05 dB lower on average, 4.60). For the figures as
# they were, run them on a CPU without VNNI, or with a models root whose DEFAULT has no vnni line:
#   mkdir -p /tmp/float && ln -sfn "$PWD"/models/*/ /tmp/float/ && echo compact-multiscale >/tmp/float/DEFAULT
#   RAINDROP_MODELS=/tmp/float scripts/results.sh SECTION
#
# Nothing here is committed automatically: images derived from Cityscapes, CamVid or the
# real raindrop photographs stay under out/ (their licences forbid redistribution).
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."
shared="${RAINDROP_SHARED_DATA:-../shared/data}"
py=.venv/bin/python
out=out/results
mkdir -p "$out"
sections=("$@")
((${#sections[@]})) || sections=(data render stats eval remove tradeoffs sheets photoreal scale flatroad largedrops coarsetrain
                                  largedropmodels sensor mirroraverage highlights multiscale veil papermodels outline trails
                                  photos windshield windshield-followup longer growth sharpness coalesce
                                  surround largewidth largedrops-all windshield2 errorsplit withoutvnni graphrewrites
                                  jitter windshieldscale router routed int8router droplets realismcontrol droplets2 infocus realismbar
                                  windshieldday fillarea finedrops lanes glassplate platerecon aperturelanes headrouter int8head headthreshold dilation coarsescales mainthreshold
                                  rim headtext headnight headdiscs workers int8default sampledlayers dry wetgate evalprogram photostally largedetail)
want() { [[ " ${sections[*]} " == *" $1 "* ]]; }
# link_set SRC DST SPLIT [LIMIT]: the first LIMIT (default 100; 0: all) samples of data set SRC
# (of manifest split SPLIT; "-" = all) linked into DST/rainy and DST/clean (and DST/mask, where
# the set has masks) under plainly named files (older renders named some samples '..-...',
# which folder walks skip as hidden), DST emptied first.
link_set() {
  rm -rf "$2" && mkdir -p "$2/rainy" "$2/clean"
  $py - "$1" "$2" "$3" "${4:-100}" <<'PY'
import json, os, sys
src, dst, split, limit = sys.argv[1:]
limit = int(limit)
n = 0
for line in open(os.path.join(src, "manifest.jsonl")):
    r = json.loads(line)
    if split != "-" and r.get("split") != split:
        continue
    name = "s" + os.path.basename(r["rainy"])
    for kind in ("rainy", "clean"):
        os.symlink(os.path.abspath(os.path.join(src, r[kind])), os.path.join(dst, kind, name))
    if r.get("mask") and os.path.isfile(os.path.join(src, r["mask"])):  # for score_outputs --masks
        os.makedirs(os.path.join(dst, "mask"), exist_ok=True)
        os.symlink(os.path.abspath(os.path.join(src, r["mask"])), os.path.join(dst, "mask", name))
    n += 1
    if n == limit:
        break
PY
}

# router_analysis: RESULTS 4.33's analysis of the router (Python on stdin; RD: the router
# section's folder, SHARED: the shared data; EXTRA_SETS: more validation sets, <name>-<split>
# folders in RD beside the five, for a what-if fit that stops after the 5-fold table; VARIANTS=1:
# the routers of RESULTS 4.34 that were not kept, on the same folds, and stop).
router_analysis() {
  $py - <<'PY'
import glob, os, sys
import cv2, numpy as np
sys.path.insert(0, "tools")
from raindrop_tools.reference import RaindropRemover
rd = os.environ["RD"]
sets = ["real-pairs-train", "val-sparse--", "val-windshield-sharp--", "val-size-512x288--", "val-size-1280x720--"]
sets += os.environ.get("EXTRA_SETS", "").split()  # more validation sets (router_analysis's callers)
def y(img): return 16 + (65.481 * img[..., 2] + 128.553 * img[..., 1] + 24.966 * img[..., 0]) / 255.0
def psnr(a, b):
    d = y(a.astype(np.float64)) - y(b.astype(np.float64)); return 10 * np.log10(255**2 / (d * d).mean())
def first(pattern): return glob.glob(pattern)[0]
def per_image(s):
    """Set s's output names, rainy images and per-image PSNR-Y rows (input, default, windshield)."""
    d0, d1 = f"{rd}/default-{s}", f"{rd}/ws-{s}"
    names, rows, ps = sorted(os.listdir(f"{d0}/out")), [], []
    for n in names:
        stem = os.path.splitext(n)[0]
        clean, rainy = cv2.imread(first(f"{d0}/set/clean/{stem}.*")), first(f"{d0}/set/rainy/{stem}.*")
        rows.append((psnr(cv2.imread(rainy), clean), psnr(cv2.imread(f"{d0}/out/{n}"), clean),
                     psnr(cv2.imread(f"{d1}/out/{n}"), clean)))
        ps.append(rainy)
    return names, ps, np.array(rows)
res, paths = {}, {}
for s in sets:
    _, paths[s], r = per_image(s)
    res[s] = r
    print(f"{s:24s} n={len(r):3d} default {np.mean(r[:, 1] - r[:, 0]):+.2f} windshield {np.mean(r[:, 2] - r[:, 0]):+.2f} "
          f"per-image best {np.mean(np.maximum(r[:, 1], r[:, 2]) - r[:, 0]):+.2f} windshield better on {np.mean(r[:, 2] > r[:, 1]):.0%}")
def working(img, size=512):
    h, w = img.shape[:2]; s = min(1.0, size / max(h, w))
    return cv2.resize(img, (round(w * s), round(h * s)), interpolation=cv2.INTER_AREA) if s < 1 else img
def blobs(path):
    g = cv2.cvtColor(working(cv2.imread(path)), cv2.COLOR_BGR2GRAY).astype(np.float32)
    a = np.abs(cv2.GaussianBlur(g, (0, 0), 1.0) - cv2.GaussianBlur(g, (0, 0), 2.5))
    return ((a == cv2.dilate(a, np.ones((5, 5), np.uint8))) & (a > 6)).sum() / g.size * 1e5
photos = sorted(glob.glob(os.path.join(os.environ["SHARED"], "real-raindrop", "*")))
for k, ps in [*paths.items(), ("photographs", photos)]:
    v = np.array([blobs(p) for p in ps])
    print(f"small-blob density {k:24s} p10 {np.percentile(v, 10):6.0f} median {np.median(v):6.0f} p90 {np.percentile(v, 90):6.0f}")
# The features and the fit are the shipped router's (tools/raindrop_tools/detector_router.py).
from raindrop_tools import detector_router as DR
from raindrop_tools.imageio import read_rgb
rem = RaindropRemover(os.environ.get("MAIN_MODELS", "models/compact-multiscale"), threads=2)  # whose detector gives the features
def feats(path):
    return DR.image_features(rem, read_rgb(path))
X = np.array([feats(p) for s in sets for p in paths[s]])
G = np.array([s for s in sets for _ in paths[s]])
# Folds by background frame (the renders' variants of one frame, _vNN, in every rendered set: val-sparse
# and windshield-sharp share the CamVid frames) or scene (a real pair's group, _tNN): never one
# background on each side of a fold.
import re
frames = np.array([("real/" if s.startswith("real") else "") + re.sub(r"_[vt]\d+$", "", os.path.splitext(os.path.basename(p))[0])
                   for s in sets for p in paths[s]])
fold_of = {f: k % 5 for k, f in enumerate(np.random.default_rng(0).permutation(np.unique(frames)))}
R = np.vstack([res[s] for s in sets]); Y = (R[:, 2] > R[:, 1]).astype(float); D = R[:, 2] - R[:, 1]
def fit(X, y, w):  # the router's predictor: weighted logistic regression (DR.fit)
    return DR.fit(X, y, w, "compact-windshield").prefers_alternative
print(f"{len(np.unique(frames))} frames or scenes in 5 folds")
for scheme in ("5-fold", "leave-one-set-out"):
    folds = np.array([fold_of[f] for f in frames]) if scheme == "5-fold" else np.unique(G, return_inverse=True)[1]
    pred = np.zeros(len(X), bool)
    for k in np.unique(folds):
        pred[folds == k] = fit(X[folds != k], Y[folds != k], np.abs(D[folds != k]) + 0.05)(X[folds == k])
    for s in sets:
        r, sel = res[s], G == s
        print(f"router {scheme:17s} {s:24s} routed {np.mean(np.where(pred[sel], r[:, 2], r[:, 1]) - r[:, 0]):+.2f} "
              f"(to windshield {pred[sel].mean():.0%})")
if os.environ.get("VARIANTS"):
    # RESULTS 4.34's routers not kept, on the same folds: features of the default detector's map
    # of a copy at a third (the coarse pass's) and at half the working scale, and the other way
    # round (compact-windshield's detector first, the router choosing the default's).
    import math
    def scaled_feats(path, divisor, models=rem):
        rgb = read_rgb(path); h, w = rgb.shape[:2]
        s = min(1.0, 512 / max(h, w)) / divisor
        size = (max(1, math.floor(w * s + 0.5)), max(1, math.floor(h * s + 0.5)))
        R_, _, _ = models.prepare(cv2.resize(rgb, size, interpolation=cv2.INTER_AREA) if divisor > 1 else rgb)
        return DR.features(models.detect(R_)[0, 0][:size[1], :size[0]])
    rem_ws = RaindropRemover("models/compact-windshield", threads=2)
    folds = np.array([fold_of[f] for f in frames])
    for name, fn, flip in (("coarse 1/3", lambda p: scaled_feats(p, 3), False), ("half", lambda p: scaled_feats(p, 2), False),
                           ("windshield first", lambda p: DR.image_features(rem_ws, read_rgb(p)), True)):
        Xv = np.array([fn(p) for s_ in sets for p in paths[s_]])
        Yv, Dv = (1 - Y, -D) if flip else (Y, D)
        pred = np.zeros(len(Xv), bool)
        for k in np.unique(folds):
            pred[folds == k] = fit(Xv[folds != k], Yv[folds != k], np.abs(Dv[folds != k]) + 0.05)(Xv[folds == k])
        for s_ in sets:
            r, sel = res[s_], G == s_
            other = pred[sel] != flip  # True: compact-windshield's output
            print(f"variant {name:16s} 5-fold {s_:24s} routed {np.mean(np.where(other, r[:, 2], r[:, 1]) - r[:, 0]):+.2f} "
                  f"(to windshield {other.mean():.0%})")
if os.environ.get("EXTRA_SETS") or os.environ.get("VARIANTS"):
    sys.exit(0)  # a what-if fit: no photographs, no test sets
router = fit(X, Y, np.abs(D) + 0.05)  # trained on every validation image
pick = router(np.array([feats(p) for p in photos]))
print(f"photographs to the windshield detector: {pick.sum()} of {len(photos)}; to the default:",
      " ".join(os.path.basename(p) for p, k in zip(photos, pick) if not k))
# Held out, once: the same router applied to the test sets.
for s in ["real-pairs-test", "test-sparse--", "test-windshield-sharp--", "test-size-512x288--", "test-size-1280x720--"]:
    names, ps, r = per_image(s)
    pick = router(np.array([feats(p) for p in ps]))
    routed = np.where(pick, r[:, 2], r[:, 1])
    # The routed outputs as a folder, for score_outputs' own protocol below.
    d0, d1 = f"{rd}/default-{s}", f"{rd}/ws-{s}"
    os.makedirs(f"{rd}/routed-{s}/out", exist_ok=True)
    for n, k in zip(names, pick):
        dst = f"{rd}/routed-{s}/out/{n}"
        if os.path.lexists(dst):
            os.remove(dst)
        os.symlink(os.path.abspath(f"{d1 if k else d0}/out/{n}"), dst)
    print(f"test {s:24s} n={len(r):3d} gain default {np.mean(r[:, 1] - r[:, 0]):+.2f} windshield "
          f"{np.mean(r[:, 2] - r[:, 0]):+.2f} routed {np.mean(routed - r[:, 0]):+.2f} (to windshield {pick.mean():.0%})")
PY
}
# alternate_times ROUNDS LABEL PHOTO... -- FLAGS...: ROUNDS rounds of `raindrop-remove PHOTO -j 2`
# (PHOTO from the real photographs) with each FLAGS in turn, wall time from the shell (process
# start to file written); lines "PHOTO FLAGS MS", LABEL standing for empty FLAGS (median_times reads them).
alternate_times() {
  local rounds="$1" label="$2" photos=() photo flags i s
  shift 2
  while [[ $1 != -- ]]; do photos+=("$1"); shift; done
  shift
  for i in $(seq "$rounds"); do
    for photo in "${photos[@]}"; do
      for flags in "$@"; do
        s=$(date +%s%N)
        # shellcheck disable=SC2086
        build/raindrop-remove "$shared/real-raindrop/$photo" "$out/alternate-times.png" -j 2 -q $flags
        echo "$photo ${flags:-$label} $(( ($(date +%s%N) - s) / 1000000 ))"
      done
    done
  done
}
# median_times FILE: FILE's lines are "KEY... MS" (timed runs); per key, in first-seen order, the
# median, minimum and maximum of the milliseconds.
median_times() {
  $py - "$1" <<'PY'
import collections, statistics, sys
t = collections.defaultdict(list)
for line in open(sys.argv[1]):
    *key, ms = line.split()
    t[" ".join(key)].append(int(ms))
for key, v in t.items():
    print(f"{key}: median {statistics.median(v):.1f} ms (min {min(v)}, max {max(v)})")
PY
}

# with_effect PRESET FILE SUFFIX EFFECT JSON: the preset's resolved scene with effects.EFFECT set to
# JSON and "-SUFFIX" added to its name, written to FILE (printed).
with_effect() {
  build/raindrop-render --scene "$1" --print-scene | $py -c '
import json, sys
scene = json.load(sys.stdin)
scene["effects"][sys.argv[1]] = json.loads(sys.argv[2])
scene["name"] += "-" + sys.argv[3]
print(json.dumps(scene, indent=2))' "$4" "$5" "$3" >"$2"
  echo "$2"
}

# size_sets SPLIT NAME: the paper preset over the Cityscapes frames of SPLIT at 512x288 and
# 1280x720 (16 variants, seed 9) in data/NAME-<size>, unless already there. With SPLIT val these
# are the renders of the size test (TrainedModels.DefaultGainsAsMuchOnLargeStreetFrames).
size_sets() {
  local s
  for s in 512x288 1280x720; do
    [[ -f "data/$2-$s/manifest.jsonl" ]] ||
      build/raindrop-render --cityscapes "$shared/cityscapes-mini" --split "$1" --variants 16 --seed 9 --size "$s" \
        --out "data/$2-$s" -q
  done
}

# real_pairs_data: the real pairs with their train/test split in data/real-pairs, unless already there.
real_pairs_data() {
  [[ -f data/real-pairs/manifest.jsonl ]] || $py -m raindrop_tools.realpairs prepare "$shared/real-pairs" --out data/real-pairs
}

# glass_droplets_438: scenes/glass-droplets.json as RESULTS 4.38-4.40 rendered it (focal length
# 4-6 mm; 4.41 made it 2.5-4), on stdout.
glass_droplets_438() {
  edited_scene 's/"focal_length_mm": \[2.5, 4\]/"focal_length_mm": [4, 6]/' scenes/glass-droplets.json
}
# glass_droplets_435: the same with the ranges RESULTS 4.35 rendered it with (glass 5-25 cm,
# footprint radius 0.015-0.12 cm, contact angles 40-90), on stdout.
glass_droplets_435() {
  local s438
  s438=$(mktemp)
  glass_droplets_438 >"$s438"
  edited_scene 's/"glass_distance_cm": \[12, 60\]/"glass_distance_cm": [5, 25]/;
                s/"footprint_radius_cm": \[0.025, 0.175\]/"footprint_radius_cm": [0.015, 0.12]/;
                s/"contact_angle_deg": \[20, 50\]/"contact_angle_deg": [40, 90]/' "$s438" 3
  rm -f "$s438"
}
# built_at COMMIT DIR: COMMIT checked out in a git worktree at DIR, its raindrop-render and
# raindrop-bench built in DIR/build (once: kept for the next run), to run beside this build.
built_at() {
  [[ -x $2/build/raindrop-bench ]] && return 0
  rm -rf "$2"
  git worktree prune
  git worktree add --detach "$2" "$1" >/dev/null
  cmake -S "$2" -B "$2/build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DRAINDROP_BUILD_TESTS=OFF >/dev/null
  cmake --build "$2/build" --target raindrop-render raindrop-bench >/dev/null
}
# bin_of before|now: the build folder of the section's older build ($before, the DIR it gave
# built_at) or of this one.
bin_of() { if [[ $1 == before ]]; then echo "$before/build"; else echo build; fi; }

# edited_scene SED FILE [N]: FILE edited by SED on stdout; fails (and prints nothing) unless N
# lines (default 1) changed, so that a scene file edited since cannot silently render unchanged.
edited_scene() {
  local text changed
  text=$(sed "$1" "$2")
  changed=$(diff <(printf '%s\n' "$text") "$2" | grep -c '^<' || true)
  if [[ $changed != "${3:-1}" ]]; then
    echo "results.sh: editing $2 changed $changed lines, not ${3:-1}: the scene file changed since" >&2
    return 1
  fi
  printf '%s\n' "$text"
}

# realism_table DIR: the realism classifier's scores in DIR/{real-raindrop,clarity}-s<seed>.json
# (one `raindrop_tools.realism` call per photo set and seed, seeds 0, 1, ...), per rendered set, as
# markdown: the classifier's accuracy, the street alone's and the drops' effect, means over the
# seeds (RESULTS 4.38, 4.40).
# paired_realism DIR PHOTOS... -- SETS...: the realism classifier crop for crop (--paired), seeds 0-5,
# against each folder of photographs PHOTOS (its JSONs DIR/<basename>-s<seed>.json), with SETS the
# --rendered arguments; then per photo folder a table of each set's accuracy, its paired differences
# to the sets named val-paper and val-real-photo (mean and sd over the seeds) and its drops' effect.
paired_realism() {
  local dir="$1" photos=() photo seed
  shift
  while [[ $1 != -- ]]; do photos+=("$1"); shift; done
  shift
  for photo in "${photos[@]}"; do
    for seed in 0 1 2 3 4 5; do
      $py -m raindrop_tools.realism --real-photos "$photo" "$@" --limit 100 --seed "$seed" --paired \
        --json "$dir/$(basename "$photo")-s$seed.json" >/dev/null
    done
  done
  $py - "$dir" "${photos[@]}" <<'PY'
import json, os, sys
import numpy as np
d = sys.argv[1]
for photos in map(os.path.basename, sys.argv[2:]):
    acc, seeds = {}, 0
    while os.path.exists(f"{d}/{photos}-s{seeds}.json"):
        for sc in json.load(open(f"{d}/{photos}-s{seeds}.json"))["photo_scores"]:
            name = sc["name"].split("(")[1].split(",")[0].removeprefix("val-")
            acc.setdefault(name, []).append((sc["classifier"]["accuracy"], sc["drops_effect"]))
        seeds += 1
    acc = {k: np.array(v) for k, v in acc.items()}
    print(f"\n{photos}, {seeds} seeds, paired: accuracy (lower is closer); difference to paper and to real-photo, "
          "mean (sd) over the seeds; drops' effect\n\n| preset | accuracy | - paper | - real-photo | drops' effect |\n"
          "| --- | ---: | ---: | ---: | ---: |")
    for name, v in acc.items():
        dp, dr = v[:, 0] - acc["paper"][:, 0], v[:, 0] - acc["real-photo"][:, 0]
        print(f"| {name} | {v[:, 0].mean():.3f} | {dp.mean():+.3f} ({dp.std(ddof=1):.3f}) | {dr.mean():+.3f} "
              f"({dr.std(ddof=1):.3f}) | {v[:, 1].mean():+.3f} |")
PY
}
realism_table() {
  $py - "$1" <<'PY'
import json, os, sys
import numpy as np
rc = sys.argv[1]
for photos in ("real-raindrop", "clarity"):
    rows = {}
    seeds = 0
    while os.path.exists(f"{rc}/{photos}-s{seeds}.json"):
        seeds += 1
    for seed in range(seeds):
        for sc in json.load(open(f"{rc}/{photos}-s{seed}.json"))["photo_scores"]:
            name = sc["name"].split("(")[1].split(",")[0]
            rows.setdefault(name, []).append((sc["classifier"]["accuracy"], sc["street"]["accuracy"], sc["drops_effect"]))
    print(f"\n{photos}, mean of {seeds} seeds\n\n| set | classifier | street alone | drops' effect (min to max) |\n| --- | ---: | ---: | ---: |")
    for name, v in rows.items():
        v = np.array(v)
        print(f"| {name} | {v[:, 0].mean():.3f} | {v[:, 1].mean():.3f} | {v[:, 2].mean():+.3f} ({v[:, 2].min():+.3f} to {v[:, 2].max():+.3f}) |")
PY
}

# beaded_sheet DIR SET_A SET_B: DIR/sheet.png (looked at, not committed), centre crops of five beaded
# photographs (DIR/clarity) at the working scale beside renders of DIR/SET_A and DIR/SET_B,
# doubled; photograph | SET_A | SET_B per row.
beaded_sheet() {
  $py - "$@" <<'PY'
import os, sys
import cv2
import numpy as np
rc, a, b = sys.argv[1:]
photos = sorted(os.listdir(f"{rc}/clarity"))[1::3][:5]
renders = sorted(os.listdir(f"{rc}/{b}/rainy"))[::17][:5]
def crop(im):
    h, w = im.shape[:2]
    im = cv2.resize(im, (512, round(h * 512 / w)), interpolation=cv2.INTER_AREA)
    h = im.shape[0]
    return cv2.resize(im[h // 2 - 64:h // 2 + 64, 128:384], None, fx=2, fy=2, interpolation=cv2.INTER_NEAREST)
rows = [np.hstack([crop(cv2.imread(f"{rc}/clarity/{p}"))] + [crop(cv2.imread(f"{rc}/{s}/rainy/{r}")) for s in (a, b)])
        for p, r in zip(photos, renders)]
cv2.imwrite(f"{rc}/sheet.png", np.vstack(rows))
PY
}

# router_alternative RUN: tools/configs/RUN.yaml trained (800 stage-1 steps from compact-windshield's
# detector, unless its checkpoint exists) and exported to out/models/RUN, and out/models/cm-RUN, the
# default with that detector as its router's alternative (the router's choice is the same: it
# reads the default's own detector). RESULTS 4.35 and 4.39.
router_alternative() {
  local run="$1"
  [[ -f "tools/runs/$run/checkpoints/stage1_step00000800.pt" ]] ||
    $py -m raindrop_tools.train --config "tools/configs/$run.yaml" --out "tools/runs/$run" \
      --init-from models/compact-windshield --stage 1
  rm -rf "out/models/$run" "out/models/cm-$run"
  mkdir -p out/models && ln -sfn "$PWD/models/paper-real-coarse" out/models/paper-real-coarse
  $py -m raindrop_tools.export --run "tools/runs/$run" --reconstruction-from models/compact-multiscale \
    --name "$run" --out "out/models/$run"
  $py -m raindrop_tools.large_drop_growth "out/models/$run" 0.35
  cp models/compact-multiscale/LARGE_DROPS "out/models/$run/"
  cp -r models/compact-multiscale "out/models/cm-$run"
  sed -i "s/^alternative compact-windshield\$/alternative $run/" "out/models/cm-$run/ROUTER"
}

# alternative_scored DIR RUN SET...: RUN trained and exported as the routed default's alternative
# (router_alternative), the routed default and it scored on each SET (score_sets, -j 2) into
# DIR/scores.txt, and both run on the 44 photographs (DIR/photos-default, DIR/photos-RUN: outputs
# and masks).
alternative_scored() {
  local dir="$1" run="$2" m flags
  shift 2
  router_alternative "$run"
  {
    score_sets "$dir" routed "-j 2" "$@"
    score_sets "$dir" "$run" "-j 2 --models out/models/cm-$run" "$@"
  } | tee "$dir/scores.txt"
  for m in default "$run"; do
    flags=()
    [[ $m == default ]] || flags=(--models "out/models/cm-$m")
    rm -rf "$dir/photos-$m" && build/raindrop-remove "$shared/real-raindrop" "$dir/photos-$m/out" \
      --mask-dir "$dir/photos-$m/masks" -q -j 2 "${flags[@]}"
  done
}

# windshield_1280_sets: windshield-sharp and windshield-day drops at 1280x720, over the 100 CamVid
# val frames (seed 11: data/val-ws-1280x720, data/val-wsday-1280x720) and the 233 test frames
# (seed 2: data/test-ws-1280x720, data/test-wsday-1280x720); each rendered once.
windshield_1280_sets() {
  local p scene set
  link_cv100
  for p in windshield-sharp:val-ws-1280x720 windshield-day:val-wsday-1280x720; do
    IFS=: read -r scene set <<<"$p"
    [[ -f data/$set/manifest.jsonl ]] || build/raindrop-render -i "$out/cv100" -o "data/$set" --scene "$scene" \
      --size 1280x720 --seed 11 -q
  done
  for p in windshield-sharp:test-ws-1280x720 windshield-day:test-wsday-1280x720; do
    IFS=: read -r scene set <<<"$p"
    [[ -f data/$set/manifest.jsonl ]] || build/raindrop-render -i "$shared/camvid/test" -o "data/$set" --scene "$scene" \
      --size 1280x720 --seed 2 -q
  done
}
# link_cv100: the first 100 CamVid val frames of 4.2, linked into out/results/cv100.
link_cv100() {
  mkdir -p "$out/cv100"
  ls "$shared/camvid/val" | head -100 | while read -r f; do ln -sf "$(realpath "$shared/camvid/val/$f")" "$out/cv100/$f"; done
}
# no_drops SRC DST: data set SRC with every rainy image replaced by its clean one (what the
# scenes alone tell apart, for the realism classifier), into DST, emptied first.
no_drops() {
  rm -rf "$2" && mkdir -p "$2" && cp "$1/manifest.jsonl" "$2/" && cp -r "$1/clean" "$1/mask" "$2/" && cp -r "$1/clean" "$2/rainy"
}
# The paper preset with the drop density of the authors' released renderer (5-7 drops, about 1%
# of the frame; docs/DESIGN.md section 1.1), everything else as it is: $out/paper-sparse.json.
paper_sparse_scene() {
  sed 's/"name": "paper"/"name": "paper-sparse"/; s/"drop_count": \[50, 70\]/"drop_count": [5, 7]/' scenes/paper.json \
    > "$out/paper-sparse.json"
}
# validation_sets: the validation sets of 4.18-4.33, unless already there: the real pairs (their
# train split), sparse paper drops and windshield-sharp drops over 100 CamVid val frames, and the
# paper preset over the Cityscapes train frames at 512x288 and 1280x720.
validation_sets() {
  real_pairs_data
  link_cv100
  paper_sparse_scene
  [[ -f data/val-sparse/manifest.jsonl ]] || build/raindrop-render -i "$out/cv100" -o data/val-sparse \
    --scene "$out/paper-sparse.json" --size 512x256 --seed 11 --variants 2 -q
  [[ -f data/val-windshield-sharp/manifest.jsonl ]] || build/raindrop-render -i "$out/cv100" \
    -o data/val-windshield-sharp --scene windshield-sharp --size 512x256 --seed 11 -q
  size_sets train val-size
}
# data/train-hi: the paper preset over the training frames rendered at 1280x640, which
# compact-multiscale and compact-windshield average down to 512x256 on loading.
render_train_hi() {
  build/raindrop-render --input "$shared/camvid/train" --input "$shared/camvid/val" \
    --cityscapes "$shared/cityscapes-mini" --split train --size 1280x640 --variants 3 --seed 3 --out data/train-hi -q
}
# detector_run NAME: tools/runs/NAME, the detector fine-tune of compact-multiscale that
# tools/configs/NAME.yaml describes (stage 1), trained unless its last checkpoint is there (the
# windshield configs' 800 steps; a run.json alone may be an interrupted run).
detector_run() {
  [[ -f "tools/runs/$1/checkpoints/stage1_step00000800.pt" ]] ||
    $py -m raindrop_tools.train --config "tools/configs/$1.yaml" --out "tools/runs/$1" \
      --init-from models/compact-multiscale --stage 1
}
# with_large_drops DIR: the model folder DIR (outside models/) reconstructs large drops as the
# default does: the default's LARGE_DROPS, and the folder it names linked in beside DIR.
with_large_drops() {
  cp models/compact-multiscale/LARGE_DROPS "$1/"
  local sibling
  sibling="$(dirname "$1")/compact-real-coarse-long"
  [[ -e $sibling ]] || ln -s "$PWD/models/compact-real-coarse-long" "$sibling"
}

# merged_training_set SUFFIX SCENE: the training set of 4.10's renders-only recipe with its lens-cover
# renders made by SCENE: CamVid train (4 variants, seed 7) and Cityscapes-mini train (20 variants,
# seed 8) at 512x256 into data/train-lens-cover-mergedSUFFIX and data/train-cs-lens-mergedSUFFIX,
# merged with data/train-windshield-day (photoreal) into data/train-mix-mergedSUFFIX.
merged_training_set() {
  build/raindrop-render -i "$shared/camvid/train" -o "data/train-lens-cover-merged$1" --scene "$2" \
    --size 512x256 --variants 4 --seed 7 -q
  build/raindrop-render --cityscapes "$shared/cityscapes-mini" --split train -o "data/train-cs-lens-merged$1" \
    --scene "$2" --size 512x256 --variants 20 --seed 8 -q
  [[ -d "data/train-mix-merged$1" ]] || $py -m raindrop_tools.merge_datasets --out "data/train-mix-merged$1" \
    "data/train-lens-cover-merged$1" data/train-windshield-day "data/train-cs-lens-merged$1"
}

# merged_models_scored DIR TAG: the renders-only recipe tools/configs/compact-lens-mergedTAG.yaml
# trained with seeds 1234 and 2 (where out/models lacks them), exported, and scored on both real
# splits (none trained on) into DIR.
merged_models_scored() {
  local m seed
  for seed in 1234 2; do
    m="compact-lens-merged$2-s$seed"
    [[ -f "out/models/$m/rdn.onnx" ]] || {
      $py -m raindrop_tools.train --config "tools/configs/compact-lens-merged$2.yaml" --out "tools/runs/$m" --set "seed=$seed"
      $py -m raindrop_tools.export --run "tools/runs/$m" --name "compact-lens-merged$2" --out "out/models/$m"
    }
    score_sets "$1" "$m" "--models out/models/$m --large-drop-models out/models/$m" real-pairs:test:0 real-pairs:train:0
  done
}

# score_sets DIR LABEL FLAGS SET...: raindrop-remove with FLAGS on each SET (name:split:limit of
# a data set under data/, linked by link_set into DIR/LABEL-name-split), scored by score_outputs.
score_sets() {
  local dir="$1" label="$2" flags="$3" set name split limit d masks
  shift 3
  for set in "$@"; do
    IFS=: read -r name split limit <<<"$set"
    d="$dir/$label-$name-$split"
    link_set "data/$name" "$d/set" "$split" "$limit"
    masks=()
    [[ -z ${SPLIT_ERROR:-} ]] || masks=(--mask-dir "$d/masks")
    # shellcheck disable=SC2086
    build/raindrop-remove "$d/set/rainy" "$d/out" -q $flags "${masks[@]}"
    [[ -z ${SPLIT_ERROR:-} ]] || masks=(--masks "$d/masks")
    $py -m raindrop_tools.score_outputs --data "$d/set" --outputs "$d/out" "${masks[@]}" --label "$label $name $split"
  done
}
# split_sets DIR LABEL FLAGS SET...: score_sets with the detected masks written too, and the
# error left split by the set's masks x the detected ones (score_outputs --masks).
split_sets() { SPLIT_ERROR=1 score_sets "$@"; }
# sweep_rule SCORES BASE: of the labels (first words) of score_sets lines in SCORES, the one the
# rule of docs/RESULTS.md 4.50 chooses over the label BASE: the mean of their gains up by at least
# 0.05 dB and no set down by more than 0.1 dB; of several, the highest mean; else BASE. Each
# label's mean on stderr.
sweep_rule() {
  $py - "$1" "$2" <<'PY'
import collections, re, sys
gains = collections.defaultdict(dict)
for line in open(sys.argv[1]):
    m = re.match(r"(\S+) (\S+ \S+): .*\(gain ([-+][0-9.]+)\)", line)
    if m:
        gains[m.group(1)][m.group(2)] = float(m.group(3))
base = gains[sys.argv[2]]
mean = {t: sum(g.values()) / len(g) for t, g in gains.items()}
for t in gains:
    print(f"# {t}: mean {mean[t]:.3f}", file=sys.stderr)
ok = [t for t, g in gains.items() if t != sys.argv[2] and mean[t] >= mean[sys.argv[2]] + 0.05
      and all(g[k] >= base[k] - 0.1 for k in base)]
print(max(ok, key=mean.get) if ok else sys.argv[2])
PY
}
# timed LABEL CMD...: runs CMD and prints "LABEL: <wall seconds> s".
timed() {
  local label="$1" s0
  shift
  s0=$(date +%s.%N)
  "$@"
  echo "$label: $(echo "$(date +%s.%N) - $s0" | bc) s"
}

# photos_changed A B: how many of the outputs in folder A differ from those of the same name in
# B, by how much (mean absolute difference in levels), and which.
photos_changed() {
  $py - "$1" "$2" <<'PY'
import os, sys
import cv2
import numpy as np
a, b = sys.argv[1:]
names = sorted(os.listdir(a))
mean = {n: float(np.abs(cv2.imread(os.path.join(a, n)).astype(int) - cv2.imread(os.path.join(b, n))).mean()) for n in names}
changed = {n: m for n, m in mean.items() if m > 0}
spread = f", by {min(changed.values()):.2f}-{max(changed.values()):.2f} levels on average" if changed else ""
print(f"{len(changed)} of {len(names)} change{spread}:", " ".join(sorted(changed)))
PY
}

if want data; then
  # The training and held-out test sets behind models/ (models/README.md). A folder that is
  # already complete is checked against these settings and left as it is.
  build/raindrop-render --input "$shared/camvid/train" --input "$shared/camvid/val" \
    --cityscapes "$shared/cityscapes-mini" --split train --size 512x256 --variants 6 --seed 1 --out data/train -q
  build/raindrop-render --input "$shared/camvid/test" \
    --cityscapes "$shared/cityscapes-mini" --split val --size 512x256 --variants 2 --seed 2 --out data/test -q
fi

if want render; then
  # Renderer: time per frame vs the I/O floor, effects, accuracy/time (docs/RESULTS.md 1).
  build/raindrop-bench render --frames 4 --repeats 3 | tee "$out/bench_render.md"
fi

if want stats; then
  # What the presets look like on the real Cityscapes frames, and the training/test sets.
  build/raindrop-render --cityscapes "$shared/cityscapes-mini" --split all --out "$out/cs-paper" -q \
    --contact-sheet "$out/cityscapes_paper_sheet.png" --sheet-rows 3
  build/raindrop-render --cityscapes "$shared/cityscapes-mini" --split all --out "$out/cs-real-photo" -q \
    --scene real-photo --contact-sheet "$out/cityscapes_real_photo_sheet.png" --sheet-rows 3
  build/raindrop-render --cityscapes "$shared/cityscapes-mini" --split all --out "$out/cs-full-physics" -q \
    --scene full-physics --contact-sheet "$out/cityscapes_full_physics_sheet.png" --sheet-rows 3
  $py -m raindrop_tools.dataset_stats "$out/cs-paper" "$out/cs-real-photo" "$out/cs-full-physics" data/train data/test \
    | tee "$out/dataset_stats.md"
fi

if want eval; then
  # Networks on the held-out synthetic set (docs/RESULTS.md 2).
  for m in compact paper compact-int8 paper-int8; do
    [[ -d models/$m ]] || continue
    OMP_NUM_THREADS=2 $py -m raindrop_tools.evaluate --data data/test --models "models/$m" --out "out/eval/$m" --threads 2
  done
  # Where the remaining error lies: inside or outside the true mask (every tenth test image).
  OMP_NUM_THREADS=2 $py -m raindrop_tools.error_split --data data/test --models models/compact --every 10 --threads 2 \
    | tee "$out/error_split_compact.json"
  # The same test frames with the drop density of the authors' released renderer (5-7 drops,
  # about 1% of the frame; docs/DESIGN.md section 1.1), everything else the paper preset.
  paper_sparse_scene
  build/raindrop-render --input "$shared/camvid/test" --cityscapes "$shared/cityscapes-mini" --split val \
    --size 512x256 --variants 2 --seed 2 --scene "$out/paper-sparse.json" --out data/test-sparse -q
  for m in compact paper; do
    [[ -d models/$m ]] || continue
    OMP_NUM_THREADS=2 $py -m raindrop_tools.evaluate --data data/test-sparse --models "models/$m" --out "out/eval-sparse/$m" --threads 2
  done
fi

if want remove; then
  # raindrop-remove per stage and GFLOP/s (docs/RESULTS.md 3).
  build/raindrop-bench remove --models models/paper --models models/compact --models models/compact-int8 --models models/paper-int8 --scale 1 --runs 5 | tee "$out/bench_remove.md"
fi

if want tradeoffs; then
  $py -m raindrop_tools.tradeoffs --bench build/raindrop-bench --eval-root out/eval --out "$out/tradeoffs"
fi

if want sheets; then
  # Removal on real raindrop photographs, with Qian et al.'s published outputs for the five
  # inputs they cover (out/results/real_*; not committed: the photographs' licences).
  rm -rf "$out/real" && mkdir -p "$out/real"
  # (models/compact: the default when RESULTS 3.3 was measured; the default is compact-multiscale now)
  build/raindrop-remove "$shared/real-raindrop" "$out/real/removed" --mask-dir "$out/real/masks" -q --models models/compact
  $py - "$shared" "$out" <<'PY'
import sys, cv2, numpy as np
from pathlib import Path
shared, out = Path(sys.argv[1]), Path(sys.argv[2])
def load(p, w=360):
    im = cv2.imread(str(p), cv2.IMREAD_COLOR)
    return cv2.resize(im, (w, int(round(im.shape[0] * w / im.shape[1]))), interpolation=cv2.INTER_AREA)
def label(im, text):
    im = im.copy(); cv2.putText(im, text, (6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA); return im
def sheet(names, path, peer):
    rows = []
    for n in names:
        src = shared / "real-raindrop" / n
        rel = Path(n)
        cells = [label(load(src), n), label(load(out / "real/masks" / rel.with_suffix(".png")), "mask"),
                 label(load(out / "real/removed" / n), "raindrop-remove")]
        if peer:
            cells.append(label(load(shared / "peer-output-qian" / n.replace("qian_demo_", "")), "Qian et al. (published)"))
        h = max(c.shape[0] for c in cells)
        rows.append(np.hstack([cv2.copyMakeBorder(c, 0, h - c.shape[0], 0, 4, cv2.BORDER_CONSTANT) for c in cells]))
    w = max(r.shape[1] for r in rows)
    cv2.imwrite(str(path), np.vstack([cv2.copyMakeBorder(r, 0, 4, 0, w - r.shape[1], cv2.BORDER_CONSTANT) for r in rows]))
qian = [f"qian_demo_case{i}.jpg" for i in range(1, 6)]
sheet(qian, out / "real_qian_sheet.png", peer=True)
others = sorted(p.name for p in (shared / "real-raindrop").iterdir() if not p.name.startswith("qian_demo"))
sheet(others[::4], out / "real_other_sheet.png", peer=False)
print("sheets:", out / "real_qian_sheet.png", out / "real_other_sheet.png")
PY
fi

if want photoreal; then
  # docs/RESULTS.md section 4: the thin-lens presets, their realism against real drops, and
  # removal on real pairs by models trained on them (models/compact-lens, tools/configs).
  # 4.1: the fast path against the reference at 512x256 and 2048x1024 (the latter's 256-ray
  # reference takes minutes).
  build/raindrop-bench render --sections lens --frames 2 --repeats 9 | tee "$out/bench_lens.md"
  build/raindrop-bench render --sections lens --frames 2 --lens-size 2048x1024 | tee "$out/bench_lens_2048.md"
  mkdir -p "$out/cv100"
  link_cv100
  for scene in paper real-photo lens-cover lens-cover-heavy lens-cover-merged windshield-day; do
    build/raindrop-render -i "$out/cv100" -o "data/val-$scene" --scene "$scene" --size 512x256 --seed 11 -q
  done
  # Rough masks on both sides (the default), then the renderer's own masks (RESULTS 4.2).
  for masks in rough own; do
    $py -m raindrop_tools.realism --real-pairs "$shared/real-pairs" --rendered data/val-paper --rendered data/val-real-photo \
      --rendered data/val-lens-cover --rendered data/val-lens-cover-heavy --rendered data/val-lens-cover-merged \
      --rendered data/val-windshield-day --limit 100 \
      --rendered-masks "$masks" --json "$out/realism-$masks.json" | tee "$out/realism-$masks.md"
  done
  # The training sets of models/compact-lens (renders only) and compact-lens-real (+ real pairs).
  for scene in lens-cover windshield-day; do
    build/raindrop-render -i "$shared/camvid/train" -o "data/train-$scene" --scene "$scene" --size 512x256 --variants 4 --seed 7 -q
  done
  build/raindrop-render --cityscapes "$shared/cityscapes-mini" --split train -o data/train-cs-lens --scene lens-cover \
    --size 512x256 --variants 20 --seed 8 -q
  $py -m raindrop_tools.merge_datasets --out data/train-mix data/train-lens-cover data/train-windshield-day data/train-cs-lens
  real_pairs_data
  # models/compact, and the unshipped compact-lens models where trained and exported into
  # out/models (docs/RESULTS.md 4.3 has the commands).
  for dir in models/compact out/models/compact-lens out/models/compact-lens-real; do
    [[ -d $dir ]] || continue
    m=$(basename "$dir")
    for split in test all; do
      $py -m raindrop_tools.evaluate --real-pairs "$shared/real-pairs" --split "$split" --models "$dir" \
        --out "$out/real-pairs-$m-$split" --no-sheets
    done
    for scene in paper lens-cover windshield-day; do
      $py -m raindrop_tools.evaluate --data "data/val-$scene" --models "$dir" --out "$out/val-$scene-$m"
    done
  done
fi

if want scale; then
  # raindrop-remove's working scale (docs/RESULTS.md 3.4): the same drops (same seed) rendered
  # on the 8 real Cityscapes frames at 512x256 and at 2048x1024, removed with compact (the
  # default when 3.4 was measured) and compact-multiscale (the default since) at the default
  # (working) scale and, with compact, at --scale 1, scored against the clean frames.
  for scene in paper lens-cover; do
    for size in 512x256 2048x1024; do
      set_dir="$out/scale-$scene-$size"
      build/raindrop-render --cityscapes "$shared/cityscapes-mini" --split all --scene $scene --size $size \
        --variants 2 --seed 5 --out "$set_dir" -q
      for m in compact compact-multiscale; do
        rm -rf "$set_dir-auto-$m" && build/raindrop-remove "$set_dir/rainy" "$set_dir-auto-$m" -q --no-large-drops --models "models/$m"
        $py -m raindrop_tools.score_outputs --data "$set_dir" --outputs "$set_dir-auto-$m" --label "$m $scene $size default scale"
      done
      if [[ $size != 512x256 ]]; then
        rm -rf "$set_dir-full" && build/raindrop-remove "$set_dir/rainy" "$set_dir-full" -q --scale 1 --no-large-drops --models models/compact
        $py -m raindrop_tools.score_outputs --data "$set_dir" --outputs "$set_dir-full" --label "compact $scene $size --scale 1"
      fi
    done
  done | tee "$out/working_scale.txt"
fi

if want flatroad; then
  # docs/RESULTS.md 4.5: the demo street's mask IoU as rendered and with 1, 2 and 4 levels of
  # Gaussian noise added (numpy, seed 0; the true mask unchanged), for models/compact and the
  # fine-tuned models under out/models where they were trained and exported.
  set_dir="$out/flatroad"
  rm -rf "$set_dir" && build/raindrop-render --demo --size 512x256 --seed 7 --out "$set_dir/set" -q
  mkdir -p "$set_dir/in" && cp "$set_dir/set/rainy/street_v00.png" "$set_dir/in/street_noise0.png"
  $py - "$set_dir" <<'PY'
import sys
import numpy as np
from PIL import Image
d = sys.argv[1]
rng = np.random.default_rng(0)
for s in (1, 2, 4):
    a = np.asarray(Image.open(f"{d}/set/rainy/street_v00.png").convert("RGB")).astype(float)
    Image.fromarray(np.clip(a + rng.normal(0, s, a.shape), 0, 255).round().astype(np.uint8)).save(f"{d}/in/street_noise{s}.png")
PY
  for dir in models/compact models/compact-multiscale models/compact-windshield out/models/compact-real out/models/compact-real-neg out/models/compact-real-flat \
             out/models/compact-real-noise; do
    [[ -d $dir ]] || continue
    m=$(basename "$dir")
    build/raindrop-remove "$set_dir/in" "$set_dir/out-$m" --models "$dir" --mask-dir "$set_dir/masks-$m" -q --no-large-drops
    $py - "$set_dir" "$m" <<'PY'
import sys
import numpy as np
from PIL import Image
d, m = sys.argv[1:]
truth = np.asarray(Image.open(f"{d}/set/mask/street_v00.png")) > 0
ious = []
for s in (0, 1, 2, 4):
    found = np.asarray(Image.open(f"{d}/masks-{m}/street_noise{s}.png")) > 0
    ious.append(f"{(truth & found).sum() / max((truth | found).sum(), 1):.3f}")
print(f"| {m} | {' / '.join(ious)} |")
PY
  done | tee "$out/flatroad.md"
fi

if want largedrops; then
  # docs/RESULTS.md 4.6: raindrop-remove with and without its coarse pass for large drops, on
  # the real pairs' test split (data/real-pairs, from `realpairs prepare`) and on the first 100
  # samples of rendered sets (photoreal above). Each set is linked into a folder of plainly
  # named files (older renders named some samples '..-...', which folder walks skip as hidden).
  for m in compact paper; do
    for flags in "" "--no-large-drops"; do
      for set in real-pairs:test test:- val-paper:- val-lens-cover:- val-windshield-day:-; do
        name="${set%%:*}" split="${set##*:}" dir="$out/largedrops/$m${flags:+-off}-$name"
        rm -rf "$dir" && link_set "data/$name" "$dir/set" "$split"
        # --large-drop-models: each model's own networks take its large drops, as when 4.6 was
        # measured (models/compact/LARGE_DROPS now hands them to another model: 4.8).
        build/raindrop-remove "$dir/set/rainy" "$dir/out" --models "models/$m" -q ${flags:---large-drop-models models/$m}
        $py -m raindrop_tools.score_outputs --data "$dir/set" --outputs "$dir/out" --label "$m $name ${flags:-(coarse pass, own networks)}"
      done
    done
  done | tee "$out/largedrops.txt"
fi

if want coarsetrain; then
  # docs/RESULTS.md 4.7: models fine-tuned for the coarse pass's scale (tools/configs/
  # compact-real-coarse*.yaml, compact-real-d.yaml; trained and exported to out/models, or
  # committed under models/), each with its own networks throughout (--large-drop-models, as
  # when 4.7 was measured; the shipped compact now differs, 4.8): the real pairs' test
  # split with and without the coarse pass, the first 100 paper-preset test samples, and the
  # demo street's mask IoU (flatroad above, no noise).
  set_dir="$out/coarsetrain"
  rm -rf "$set_dir" && build/raindrop-render --demo --size 512x256 --seed 7 --out "$set_dir/street" -q
  for dir in models/compact out/models/compact-real-d out/models/compact-real-coarse out/models/compact-real-coarse-det \
             out/models/compact-real-coarse-lens models/compact-real-coarse-long; do
    [[ -d $dir ]] || continue
    m=$(basename "$dir")
    for run in real-pairs:test: real-pairs:test:--no-large-drops test:-:; do
      IFS=: read -r name split flags <<<"$run"
      d="$set_dir/$m-$name${flags:+-off}"
      rm -rf "$d" && link_set "data/$name" "$d/set" "$split"
      build/raindrop-remove "$d/set/rainy" "$d/out" --models "$dir" -q ${flags:---large-drop-models $dir}
      $py -m raindrop_tools.score_outputs --data "$d/set" --outputs "$d/out" --label "$m $name ${flags:-(coarse pass, own networks)}"
    done
    build/raindrop-remove "$set_dir/street/rainy/street_v00.png" "$set_dir/$m-street.png" --models "$dir" \
      --large-drop-models "$dir" --mask "$set_dir/$m-street-mask.png" -q
    $py - "$set_dir" "$m" <<'PY'
import sys
import numpy as np
from PIL import Image
d, m = sys.argv[1:]
truth = np.asarray(Image.open(f"{d}/street/mask/street_v00.png")) > 0
found = np.asarray(Image.open(f"{d}/{m}-street-mask.png")) > 0
print(f"{m} demo street mask IoU {(truth & found).sum() / max((truth | found).sum(), 1):.3f}")
PY
  done | tee "$out/coarsetrain.txt"
fi

if want largedropmodels; then
  # docs/RESULTS.md 4.8: which models reconstruct the coarse pass's large drops. `compact` with
  # its own networks throughout (as before models/compact/LARGE_DROPS), `compact` as shipped
  # (large drops by compact-real-coarse-long), and compact-real-coarse-long throughout: the real
  # pairs' test and train splits, the first 100 paper-preset test frames, all 470 sparse frames,
  # the first 100 of three thin-lens val sets (photoreal above), and the mask IoU on both demo
  # frames (checkerboard, street).
  set_dir="$out/largedropmodels"
  rm -rf "$set_dir" && build/raindrop-render --demo --size 512x256 --seed 7 --out "$set_dir/demo" -q
  for run in "compact-alone:--models models/compact --large-drop-models models/compact" \
             "compact-shipped:--models models/compact" \
             "compact-real-coarse-long:--models models/compact-real-coarse-long"; do
    label="${run%%:*}" flags="${run#*:}"
    score_sets "$set_dir" "$label" "$flags" real-pairs:test:100 real-pairs:train:100 test:-:100 test-sparse:-:0 \
               val-lens-cover:-:100 val-windshield-day:-:100 val-lens-cover-merged:-:100
    # shellcheck disable=SC2086
    build/raindrop-remove "$set_dir/demo/rainy" "$set_dir/$label-demo" --mask-dir "$set_dir/$label-demo-masks" -q $flags
    $py - "$set_dir" "$label" <<'PY'
import sys
from pathlib import Path
import numpy as np
from PIL import Image
d, label = Path(sys.argv[1]), sys.argv[2]
for truth_file in sorted((d / "demo/mask").iterdir()):
    truth = np.asarray(Image.open(truth_file)) > 0
    found = np.asarray(Image.open(d / f"{label}-demo-masks" / truth_file.name)) > 0
    print(f"{label} demo {truth_file.stem} mask IoU {(truth & found).sum() / max((truth | found).sum(), 1):.3f}")
PY
  done | tee "$out/largedropmodels.txt"
fi

if want sensor; then
  # docs/RESULTS.md 4.9: the scene effect "sensor" (noise and JPEG on the rainy image only): its
  # cost per 2048x1024 frame, and the realism of lens-cover-heavy with it (same frames, seed and
  # drops as data/val-lens-cover-heavy from photoreal above; the sensor draws its own stream).
  build/raindrop-bench render --sections effects --frames 2 --repeats 3 | tee "$out/bench_effects_sensor.md"
  mkdir -p "$out/sensor" "$out/cv100"
  link_cv100
  sets=()
  for variant in 'noise:{"noise_levels": [0.5, 1.5]}' 'jpeg:{"noise_levels": 0, "jpeg_quality": [75, 95]}' \
                 'noise-jpeg:{"noise_levels": [1, 3], "jpeg_quality": [75, 95]}'; do
    name="${variant%%:*}" sensor="${variant#*:}"
    $py - "$name" "$sensor" "$out/sensor/lens-cover-heavy-$name.json" <<'PY'
import json, sys
name, sensor, path = sys.argv[1:]
text = open("scenes/lens-cover-heavy.json").read()
scene = json.loads(text[text.index("{"):])  # after the comment lines
scene["name"] = f"lens-cover-heavy-{name}"
scene["effects"]["sensor"] = json.loads(sensor)
open(path, "w").write(json.dumps(scene, indent=2))
PY
    build/raindrop-render -i "$out/cv100" -o "data/val-lens-cover-heavy-$name" --scene "$out/sensor/lens-cover-heavy-$name.json" \
      --size 512x256 --seed 11 -q
    sets+=(--rendered "data/val-lens-cover-heavy-$name")
  done
  $py -m raindrop_tools.realism --real-pairs "$shared/real-pairs" --rendered data/val-lens-cover-heavy "${sets[@]}" --limit 100 \
    | tee "$out/realism-sensor.md"
fi

if want mirroraverage; then
  # docs/RESULTS.md 4.11: the shipped default (its coarse pass mirror-averages its fills) with and
  # without --mirror-average (the working-scale pass too): the real pairs' test and train
  # splits, all 470 paper-preset test frames and all 470 sparse frames, the first 100 of two
  # thin-lens val sets (photoreal above); then the bench's table of what the option costs.
  set_dir="$out/mirroraverage"
  # (models/compact: the default when 4.11 was measured)
  for run in "default:--models models/compact" "mirror-average:--models models/compact --mirror-average"; do
    label="${run%%:*}" flags="${run#*:}"
    score_sets "$set_dir" "$label" "$flags" real-pairs:test:100 real-pairs:train:100 test:-:0 test-sparse:-:0 \
               val-lens-cover:-:100 val-windshield-day:-:100
  done | tee "$out/mirroraverage.txt"
  build/raindrop-bench remove --models models/compact --threads 2 --size 1280x720 --runs 9 | tee "$out/bench_remove_mirroraverage.md"
fi

if want highlights; then
  # docs/RESULTS.md 4.12: the scene effect "highlights" (clipped pixels lifted before the lens
  # spreads them). Each thin-lens day preset is rendered as it is (without the effect) and with
  # it (same frames, seed and drops: its gain is drawn last), and lens-cover-merged with several
  # gain ranges, all measured against the real pairs' train split; then 4.10's renders-only
  # recipe is retrained on lens-cover-merged with gains 4-16 and 2-8 and scored on all 100 real
  # pairs (none trained on) beside compact-lens-merged; and the effect's cost.
  hl="$out/highlights"
  mkdir -p "$hl" "$out/cv100"
  link_cv100
  # with_highlights PRESET THRESHOLD LO HI: the preset with effects.highlights, written to
  # $hl/PRESET-highlights-LO-HI.json (printed).
  with_highlights() {
    with_effect "$1" "$hl/$1-highlights-$3-$4.json" "highlights-$3-$4" highlights "{\"threshold\": $2, \"gain\": [$3, $4]}"
  }
  render_val() { rm -rf "$hl/val-$1" && build/raindrop-render -i "$out/cv100" -o "$hl/val-$1" --scene "$2" --size 512x256 --seed 11 -q; }
  sets=()
  for scene in paper lens-cover lens-cover-heavy lens-cover-merged windshield-day real-photo; do
    render_val "$scene" "$scene"
    sets+=(--rendered "$hl/val-$scene")
    [[ $scene == paper ]] && continue
    render_val "$scene-highlights-4-16" "$(with_highlights "$scene" 0.9 4 16)"
    sets+=(--rendered "$hl/val-$scene-highlights-4-16")
  done
  for gain in 2:8 4:32 8:32 16:64 8:8; do
    render_val "lens-cover-merged-highlights-${gain/:/-}" "$(with_highlights lens-cover-merged 0.9 "${gain%:*}" "${gain#*:}")"
    sets+=(--rendered "$hl/val-lens-cover-merged-highlights-${gain/:/-}")
  done
  $py -m raindrop_tools.realism --real-pairs "$shared/real-pairs" "${sets[@]}" --limit 100 \
    --json "$hl/realism.json" | tee "$hl/realism.md"
  # Transfer: tools/configs/compact-lens-merged-hl.yaml (gain 4-16) and -hl28.yaml (2-8), whose
  # headers list these renders, against compact-lens-merged (4.10); renders only.
  for run in hl:4:16 hl28:2:8; do
    IFS=: read -r tag lo hi <<<"$run"
    scene_file="$(with_highlights lens-cover-merged 0.9 "$lo" "$hi")"
    merged_training_set "-$tag" "$scene_file"
    [[ -f "out/models/compact-lens-merged-$tag/rdn.onnx" ]] || {
      $py -m raindrop_tools.train --config "tools/configs/compact-lens-merged-$tag.yaml" --out "tools/runs/compact-lens-merged-$tag"
      $py -m raindrop_tools.export --run "tools/runs/compact-lens-merged-$tag" --out "out/models/compact-lens-merged-$tag"
    }
  done
  for m in compact-lens-merged compact-lens-merged-hl28 compact-lens-merged-hl; do
    score_sets "$hl" "$m" "--models out/models/$m --large-drop-models out/models/$m" real-pairs:test:0 real-pairs:train:0
  done | tee "$hl/real-pairs.txt"
  build/raindrop-bench render --sections effects --frames 2 --repeats 9 | tee "$hl/bench_effects.md"
fi

if want multiscale; then
  # docs/RESULTS.md 3.4, *Networks for frames larger than the working size*: the default (compact-multiscale) against
  # compact on the same drops at full size and at the working size, on frames no model trained
  # on (Cityscapes val at 1280x720 and 512x288, CamVid test, 480x360 frames enlarged to 960x720, and at 512x384;
  # paper preset, seed 9), and on the sets of the model card's criteria (data/test from the data
  # section, data/test-sparse from the eval section: run those first). The training set it
  # was fine-tuned on (besides data/train) is data/train-hi below; the model itself:
  #   train --config tools/configs/compact-multiscale.yaml --out tools/runs/compact-multiscale --init-from models/compact
  # and its int8 copy: quantize --models models/compact-multiscale --data data/train --out models/compact-multiscale-int8
  render_train_hi
  ms="$out/multiscale"
  mkdir -p "$ms"
  for set in "cs 1280x720" "cs 512x288" "cv 960x720" "cv 512x384"; do
    read -r src size <<<"$set"
    if [[ $src == cs ]]; then from=(--cityscapes "$shared/cityscapes-mini" --split val --limit 2 --variants 16)
    else from=(--input "$shared/camvid/test" --limit 100 --variants 1); fi
    build/raindrop-render "${from[@]}" --size "$size" --seed 9 --out "$ms/$src-$size" -q
  done
  real_pairs_data
  for m in compact compact-multiscale compact-multiscale-int8; do
    for set in cs-1280x720 cs-512x288 cv-960x720 cv-512x384; do
      rm -rf "$ms/$set-$m" && build/raindrop-remove "$ms/$set/rainy" "$ms/$set-$m" -q --models "models/$m"
      $py -m raindrop_tools.score_outputs --data "$ms/$set" --outputs "$ms/$set-$m" --label "$m $set"
    done
    score_sets "$ms" "$m" "--models models/$m" real-pairs:test:0 real-pairs:train:0 test:-:100 test-sparse:-:0
    # without the coarse pass, and with the model's own networks for its large drops
    score_sets "$ms" "$m-no-coarse" "--models models/$m --no-large-drops" real-pairs:test:0
    score_sets "$ms" "$m-own-large" "--models models/$m --large-drop-models models/$m" real-pairs:test:0
  done | tee "$ms/scores.txt"
  # The model card's Python-reference rows (demo street IoU: the flatroad section).
  for set in test test-sparse; do
    for m in compact-multiscale compact-multiscale-int8; do
      OMP_NUM_THREADS=2 $py -m raindrop_tools.evaluate --data "data/$set" --models "models/$m" \
        --out "out/${set/#test/eval}/$m" --threads 2
    done
  done
fi

if want veil; then
  # docs/RESULTS.md 4.13: the scene effect "veil" (the haze of wet glass). lens-cover rendered on the
  # 100 CamVid val frames of 4.2 as it is and with four optical-depth ranges (same seed, so the same
  # drops), measured against the real pairs' train split; the renders-only recipe of 4.10 retrained
  # with veiled lens-cover-merged renders beside compact-lens-merged, two seeds each, scored on both
  # real splits (none trained on); the effect's cost. Then 4.8's second attempt at large-drop
  # networks (tools/configs/compact-large-drops-2.yaml) against compact-real-coarse-long in the
  # default's coarse pass (needs data/train-mix from photoreal, data/real-pairs, the val sets).
  vd="$out/veil"
  mkdir -p "$vd" "$out/cv100"
  link_cv100
  # with_veil PRESET LO HI: the preset with effects.veil (optical depth LO-HI, spread 2-10 degrees),
  # written to $vd/PRESET-veil-LO-HI.json (printed).
  with_veil() {
    with_effect "$1" "$vd/$1-veil-$2-$3.json" "veil-$2-$3" veil "{\"optical_depth\": [$2, $3], \"spread_deg\": [2, 10]}"
  }
  rm -rf "$vd/val-plain" && build/raindrop-render -i "$out/cv100" -o "$vd/val-plain" --scene lens-cover --size 512x256 --seed 11 -q
  sets=(--rendered "$vd/val-plain")
  for depth in 0.005:0.02 0.01:0.03 0.02:0.06 0.04:0.1; do
    lo="${depth%:*}" hi="${depth#*:}"
    rm -rf "$vd/val-$lo-$hi"
    veiled="$(with_veil lens-cover "$lo" "$hi")"
    build/raindrop-render -i "$out/cv100" -o "$vd/val-$lo-$hi" --scene "$veiled" --size 512x256 --seed 11 -q
    sets+=(--rendered "$vd/val-$lo-$hi")
  done
  $py -m raindrop_tools.realism --real-pairs "$shared/real-pairs" "${sets[@]}" --limit 100 --json "$vd/realism.json" | tee "$vd/realism.md"
  scene_file="$(with_veil lens-cover-merged 0.005 0.02)"
  for tag in "" -veil; do
    scene=lens-cover-merged
    [[ -n $tag ]] && scene="$scene_file"
    merged_training_set "$tag" "$scene"
    merged_models_scored "$vd" "$tag"
  done | tee "$vd/real-pairs.txt"
  build/raindrop-bench render --sections effects --frames 2 --repeats 3 | tee "$vd/bench_effects.md"
  # 4.8, second attempt: large-drop networks trained further, in the default's coarse pass.
  [[ -f out/models/compact-large-drops-2/rdn.onnx ]] || {
    $py -m raindrop_tools.train --config tools/configs/compact-large-drops-2.yaml --out tools/runs/compact-large-drops-2 \
      --init-from models/compact-real-coarse-long
    $py -m raindrop_tools.export --run tools/runs/compact-large-drops-2 --out out/models/compact-large-drops-2
  }
  for m in compact-real-coarse-long compact-large-drops-2; do
    dir=models/$m
    [[ -d $dir ]] || dir=out/models/$m
    score_sets "$vd" "ld-$m" "--large-drop-models $dir" real-pairs:train:100 val-lens-cover:-:100 val-windshield-day:-:100 \
               test:-:100 test-sparse:-:100 real-pairs:test:100
  done | tee "$vd/large-drops-2.txt"
fi

if want papermodels; then
  # docs/RESULTS.md 4.14: paper with and without its large-drop networks (models/paper/LARGE_DROPS),
  # and paper-multiscale, on the sets of its criteria (the multiscale section's Cityscapes renders,
  # data/test, data/test-sparse, the real pairs, two thin-lens val sets: run those sections first).
  # The model: train --config tools/configs/paper-multiscale.yaml --out tools/runs/paper-multiscale
  #   --init-from models/paper, then export --run tools/runs/paper-multiscale --name paper-multiscale
  pm="$out/papermodels"
  mkdir -p "$pm"
  for run in "paper-own:--models models/paper --large-drop-models models/paper" "paper:--models models/paper" \
             "paper-multiscale-own:--models models/paper-multiscale --large-drop-models models/paper-multiscale" \
             "paper-multiscale:--models models/paper-multiscale"; do
    label="${run%%:*}" flags="${run#*:}"
    score_sets "$pm" "$label" "$flags" real-pairs:train:100 real-pairs:test:100 test:-:100 test-sparse:-:100 \
               val-lens-cover:-:100 val-windshield-day:-:100
    for size in 1280x720 512x288; do
      # shellcheck disable=SC2086
      build/raindrop-remove "$out/multiscale/cs-$size/rainy" "$pm/$label-cs-$size" -q $flags
      $py -m raindrop_tools.score_outputs --data "$out/multiscale/cs-$size" --outputs "$pm/$label-cs-$size" --label "$label cs $size"
    done
  done | tee "$out/papermodels.txt"
fi

if want outline; then
  # docs/RESULTS.md 4.15: the scene effect "outline" (irregular contact lines). lens-cover-merged and
  # windshield-day rendered on the 100 CamVid val frames of 4.2 as they are and with two peak
  # ranges, measured against the real pairs' train split (solidity: drop area over its convex
  # hull's); the renders-only recipe of 4.10 retrained with every rendered part made with outlines
  # (lens-cover-merged, windshield-day, Cityscapes lens-cover-merged), beside compact-lens-merged,
  # two seeds each, scored on both real splits (none trained on); the effect's cost.
  od="$out/outline"
  mkdir -p "$od" "$out/cv100"
  link_cv100
  sets=()
  for preset in lens-cover-merged windshield-day; do
    for peak in none 0:0.3 0.1:0.5; do
      scene=$preset
      [[ $peak == none ]] || scene="$(with_effect "$preset" "$od/$preset-outline-${peak/:/-}.json" "outline-${peak/:/-}" \
        outline "{\"peak_deviation\": [${peak/:/, }], \"modes\": 6}")"
      name="val-$preset-${peak/:/-}"
      rm -rf "$od/$name" && build/raindrop-render -i "$out/cv100" -o "$od/$name" --scene "$scene" --size 512x256 --seed 11 -q
      sets+=(--rendered "$od/$name")
    done
  done
  $py -m raindrop_tools.realism --real-pairs "$shared/real-pairs" "${sets[@]}" --limit 100 --json "$od/realism.json" | tee "$od/realism.md"
  # Transfer: every rendered part of the training mix with outlines (peak 0-0.3), against the same mix without.
  for preset in lens-cover-merged windshield-day; do
    with_effect "$preset" "$od/$preset-outline.json" outline outline '{"peak_deviation": [0, 0.3], "modes": 6}' >/dev/null
  done
  for tag in "" -outline; do
    lcm=lens-cover-merged wsd=windshield-day
    [[ -n $tag ]] && lcm="$od/lens-cover-merged-outline.json" wsd="$od/windshield-day-outline.json"
    [[ -d data/train-windshield-day$tag ]] || build/raindrop-render -i "$shared/camvid/train" -o "data/train-windshield-day$tag" \
      --scene "$wsd" --size 512x256 --variants 4 --seed 7 -q
    build/raindrop-render -i "$shared/camvid/train" -o "data/train-lens-cover-merged$tag" --scene "$lcm" \
      --size 512x256 --variants 4 --seed 7 -q
    build/raindrop-render --cityscapes "$shared/cityscapes-mini" --split train -o "data/train-cs-lens-merged$tag" \
      --scene "$lcm" --size 512x256 --variants 20 --seed 8 -q
    [[ -d "data/train-mix-merged$tag" ]] || $py -m raindrop_tools.merge_datasets --out "data/train-mix-merged$tag" \
      "data/train-lens-cover-merged$tag" "data/train-windshield-day$tag" "data/train-cs-lens-merged$tag"
    merged_models_scored "$od" "$tag"
  done | tee "$od/real-pairs.txt"
  build/raindrop-bench render --sections effects --frames 6 --repeats 3 | tee "$od/bench_effects.md"
fi

if want trails; then
  # docs/RESULTS.md 4.16: the scene effect "trails" (drops that slid leave streaks uphill).
  # lens-cover-merged and windshield-day rendered on the 100 CamVid val frames of 4.2 with and
  # without trails (defaults), measured against the real pairs' train split; the renders-only
  # recipe of 4.10 retrained with every rendered part made with trails, beside compact-lens-merged
  # (the models of the outline section, reused where they exist), two seeds each, scored on both
  # real splits (none trained on); the effect's cost.
  td="$out/trails" sets=()
  link_cv100
  mkdir -p "$td"
  for preset in lens-cover-merged windshield-day; do
    with_effect "$preset" "$td/$preset-trails.json" trails trails '{}' >/dev/null
    for tag in "" -trails; do
      scene=$preset
      [[ -n $tag ]] && scene="$td/$preset-trails.json"
      rm -rf "$td/val-$preset$tag" && build/raindrop-render -i "$out/cv100" -o "$td/val-$preset$tag" --scene "$scene" \
        --size 512x256 --seed 11 -q
      sets+=(--rendered "$td/val-$preset$tag")
    done
  done
  $py -m raindrop_tools.realism --real-pairs "$shared/real-pairs" "${sets[@]}" --limit 100 --json "$td/realism.json" | tee "$td/realism.md"
  for tag in "" -trails; do
    lcm=lens-cover-merged wsd=windshield-day
    [[ -n $tag ]] && lcm="$td/lens-cover-merged-trails.json" wsd="$td/windshield-day-trails.json"
    [[ -d data/train-windshield-day$tag ]] || build/raindrop-render -i "$shared/camvid/train" -o "data/train-windshield-day$tag" \
      --scene "$wsd" --size 512x256 --variants 4 --seed 7 -q
    [[ -d data/train-lens-cover-merged$tag ]] || build/raindrop-render -i "$shared/camvid/train" \
      -o "data/train-lens-cover-merged$tag" --scene "$lcm" --size 512x256 --variants 4 --seed 7 -q
    [[ -d data/train-cs-lens-merged$tag ]] || build/raindrop-render --cityscapes "$shared/cityscapes-mini" --split train \
      -o "data/train-cs-lens-merged$tag" --scene "$lcm" --size 512x256 --variants 20 --seed 8 -q
    [[ -d "data/train-mix-merged$tag" ]] || $py -m raindrop_tools.merge_datasets --out "data/train-mix-merged$tag" \
      "data/train-lens-cover-merged$tag" "data/train-windshield-day$tag" "data/train-cs-lens-merged$tag"
    merged_models_scored "$td" "$tag"
  done | tee "$td/real-pairs.txt"
  build/raindrop-bench render --sections effects --frames 6 --repeats 3 | tee "$td/bench_effects.md"
fi

if want photos; then
  # docs/RESULTS.md 4.17: the presets against the 44 real raindrop photographs (windshields and
  # lenses, no clean images: the classifier alone), beside the same CamVid frames without drops
  # (the rainy images replaced by the clean ones: what the scenes alone tell apart); three seeds.
  pd="$out/photos" sets=()
  link_cv100
  mkdir -p "$pd"
  for preset in paper real-photo windshield-day lens-cover-merged; do
    rm -rf "$pd/val-$preset" && build/raindrop-render -i "$out/cv100" -o "$pd/val-$preset" --scene "$preset" \
      --size 512x256 --seed 11 -q
    sets+=(--rendered "$pd/val-$preset")
  done
  no_drops "$pd/val-paper" "$pd/val-no-drops"
  for seed in 0 1 2; do
    $py -m raindrop_tools.realism --real-photos "$shared/real-raindrop" --rendered "$pd/val-no-drops" "${sets[@]}" \
      --limit 100 --seed "$seed" --json "$pd/realism-photos-s$seed.json" | tee "$pd/realism-photos-s$seed.md"
  done
  # The phone-aperture trial (now the windshield-sharp preset: windshield-day with f/4-11 and a
  # 4-6 mm lens), beside windshield-day.
  rm -rf "$pd/val-windshield-sharp" && build/raindrop-render -i "$out/cv100" -o "$pd/val-windshield-sharp" \
    --scene windshield-sharp --size 512x256 --seed 11 -q
  for seed in 0 1 2; do
    $py -m raindrop_tools.realism --real-photos "$shared/real-raindrop" --rendered "$pd/val-windshield-day" \
      --rendered "$pd/val-windshield-sharp" --limit 100 --seed "$seed" | tee "$pd/realism-sharp-s$seed.md"
  done
fi

if want windshield; then
  # docs/RESULTS.md 4.18: compact-windshield, the default's detector fine-tuned on windshield-sharp
  # renders beside the paper preset's (needs data/train from the data section and data/test,
  # data/test-sparse from the eval section). Training set, run and model folder:
  build/raindrop-render -i "$shared/camvid/train" -o data/train-windshield-sharp --scene windshield-sharp \
    --size 512x256 --variants 4 --seed 7 -q
  render_train_hi
  if [[ ! -f models/compact-windshield/rdn.onnx ]]; then
    detector_run compact-windshield
    $py -m raindrop_tools.export --run tools/runs/compact-windshield --reconstruction-from models/compact-multiscale \
      --out models/compact-windshield
    cp models/compact-multiscale/LARGE_DROPS models/compact-windshield/
  fi
  # The first run (no larger frames; not committed), whose threshold sweep chose 0.45:
  if [[ ! -d out/models/compact-windshield-first ]]; then
    detector_run compact-windshield-first
    $py -m raindrop_tools.export --run tools/runs/compact-windshield-first \
      --reconstruction-from models/compact-multiscale --out out/models/compact-windshield-first
    with_large_drops out/models/compact-windshield-first
  fi
  # Validation sets (the threshold was chosen on these): sparse paper drops over 100 CamVid val
  # frames, and the real pairs' train split; then windshield-sharp drops over the same frames.
  link_cv100
  paper_sparse_scene
  build/raindrop-render -i "$out/cv100" -o data/val-sparse --scene "$out/paper-sparse.json" --size 512x256 \
    --seed 11 --variants 2 -q
  build/raindrop-render -i "$out/cv100" -o data/val-windshield-sharp --scene windshield-sharp --size 512x256 --seed 11 -q
  real_pairs_data
  wd="$out/windshield"
  mkdir -p "$wd"
  score_sets "$wd" "compact-multiscale-t0.3" "--models models/compact-multiscale" real-pairs:train:0 val-sparse:-:0 \
    | tee "$wd/threshold.txt"
  for t in 0.3 0.45 0.6; do
    score_sets "$wd" "compact-windshield-first-t$t" "--models out/models/compact-windshield-first --threshold $t" \
      real-pairs:train:0 val-sparse:-:0
  done | tee -a "$wd/threshold.txt"
  for t in 0.45 0.6 0.75; do
    score_sets "$wd" "compact-windshield-t$t" "--models models/compact-windshield --surround-fill-area 150 --threshold $t" \
      real-pairs:train:0 val-sparse:-:0
  done | tee -a "$wd/threshold.txt"
  for m in models/compact-multiscale out/models/compact-windshield-first models/compact-windshield; do
    score_sets "$wd" "$(basename "$m")" "--models $m" real-pairs:test:0 test-sparse:-:0 val-windshield-sharp:-:100 test:-:100
  done | tee "$wd/scores.txt"
  # The test-set rows at other thresholds: the committed run at the first run's 0.45, the first
  # run at its config's original 0.3 (real pairs and sparse only).
  score_sets "$wd" "compact-windshield-t0.45" "--models models/compact-windshield --surround-fill-area 150 --threshold 0.45" \
    real-pairs:test:0 test-sparse:-:0 val-windshield-sharp:-:100 test:-:100 | tee -a "$wd/scores.txt"
  score_sets "$wd" "compact-windshield-first-t0.3" "--models out/models/compact-windshield-first --threshold 0.3" \
    real-pairs:test:0 test-sparse:-:0 | tee -a "$wd/scores.txt"
  # (the size target: build/raindrop_remove_tests --gtest_filter='*DefaultGainsAsMuchOnLargeStreetFrames'
  # with models/DEFAULT naming the model; the demo street's mask IoU: the flatroad section)
  # The 44 real photographs, both models (not committed: licences).
  for m in compact-multiscale compact-windshield; do
    rm -rf "$wd/real-$m" && build/raindrop-remove "$shared/real-raindrop" "$wd/real-$m/removed" \
      --mask-dir "$wd/real-$m/masks" -q --models "models/$m"
  done
fi

if want windshield-followup; then
  # docs/RESULTS.md 4.19: why compact-windshield stays an option (after the windshield section:
  # needs its data, out/models, models/compact-windshield and its run folder).
  # Validation size gap: the 6 Cityscapes *train* frames (the size test uses the 2 val frames),
  # paper drops, at 512x288 and 1280x720; windshield-sharp drops over 100 CamVid val frames too.
  link_cv100
  for s in 512x288 1280x720; do
    build/raindrop-render --cityscapes "$shared/cityscapes-mini" --split train --variants 16 --seed 9 --size "$s" \
      --out "data/val-size-$s" -q
    build/raindrop-render -i "$out/cv100" --scene windshield-sharp --size "$s" --variants 1 --seed 11 \
      --out "data/val-ws-$s" -q
  done
  fw="$out/windshield-followup"
  mkdir -p "$fw"
  for m in compact-multiscale compact-windshield; do
    score_sets "$fw" "$m" "--models models/$m" val-size-512x288:-:0 val-size-1280x720:-:0 val-ws-512x288:-:0 \
      val-ws-1280x720:-:0
  done | tee "$fw/sizes.txt"
  # A second run with more averaged-down renders, exported at three thresholds.
  detector_run compact-windshield-hi
  for t in 0.45 0.6 0.75; do
    $py -m raindrop_tools.export --run tools/runs/compact-windshield-hi --reconstruction-from models/compact-multiscale \
      --threshold "$t" --out "out/models/hi-$t/compact-windshield"
    with_large_drops "out/models/hi-$t/compact-windshield"
    score_sets "$fw" "hi-$t" "--models out/models/hi-$t/compact-windshield" real-pairs:train:0 val-sparse:-:0 \
      val-size-512x288:-:0 val-size-1280x720:-:0
  done | tee "$fw/hi.txt"
  # The committed run's own 3RN (stage 1 trains one) with the shipped detector; its RFN is
  # compact-multiscale's (the run started from those graphs, and stage 1 does not train it). The
  # windshield section trains that run only where the model folder is missing: here it is needed.
  detector_run compact-windshield
  $py -m raindrop_tools.export --run tools/runs/compact-windshield --allow-incomplete --threshold 0.75 \
    --name compact-windshield --out out/models/own-3rn/compact-windshield
  with_large_drops out/models/own-3rn/compact-windshield
  score_sets "$fw" own-3rn "--models out/models/own-3rn/compact-windshield" real-pairs:train:0 val-sparse:-:0 \
    val-ws-512x288:-:0 | tee "$fw/own-3rn.txt"
  # A wider dilation (5 instead of the models' 3), both models, on the validation sets; then the
  # default with it on the test sets.
  for m in compact-multiscale compact-windshield; do
    score_sets "$fw" "$m-d5" "--models models/$m --dilation 5" real-pairs:train:0 val-sparse:-:0
  done | tee "$fw/dilation.txt"
  score_sets "$fw" compact-multiscale-d5 "--models models/compact-multiscale --dilation 5" real-pairs:test:0 \
    test-sparse:-:0 | tee -a "$fw/dilation.txt"
fi

if want longer; then
  # compact-multiscale trained for longer (tools/configs/compact-multiscale-long.yaml, docs/RESULTS.md
  # 4.20): needs data/train and data/train-hi (data, multiscale sections) and the validation sets
  # (data/val-sparse, data/val-windshield-sharp, data/real-pairs: windshield section).
  lg="$out/longer"
  mkdir -p "$lg"
  [[ -f tools/runs/compact-multiscale-long/checkpoints/stage2_step00000600.pt ]] ||
    $py -m raindrop_tools.train --config tools/configs/compact-multiscale-long.yaml \
      --out tools/runs/compact-multiscale-long --init-from models/compact-multiscale --threads 2 --no-progress
  $py -m raindrop_tools.export --run tools/runs/compact-multiscale-long --out out/models/long/compact-multiscale-long
  with_large_drops out/models/long/compact-multiscale-long
  # Its 3RN and RFN behind compact-windshield's detector: the run exported under that model's name
  # and threshold (the graphs of one folder must agree on both), its rdn.onnx then the shipped one.
  $py -m raindrop_tools.export --run tools/runs/compact-multiscale-long --name compact-windshield --threshold 0.75 \
    --out out/models/long-ws/compact-windshield
  cp models/compact-windshield/rdn.onnx out/models/long-ws/compact-windshield/
  with_large_drops out/models/long-ws/compact-windshield
  for m in compact-multiscale compact-windshield; do
    score_sets "$lg" "$m" "--models models/$m -j 2" real-pairs:train:0 val-sparse:-:0 val-windshield-sharp:-:0
  done | tee "$lg/shipped.txt"
  score_sets "$lg" long "--models out/models/long/compact-multiscale-long -j 2" real-pairs:train:0 val-sparse:-:0 \
    val-windshield-sharp:-:0 | tee "$lg/long.txt"
  score_sets "$lg" long-ws "--models out/models/long-ws/compact-windshield -j 2" real-pairs:train:0 val-sparse:-:0 \
    val-windshield-sharp:-:0 | tee "$lg/long-ws.txt"
  # It met the criteria: the test sets, and the size gap on the multiscale section's Cityscapes val renders.
  for m in long:out/models/long/compact-multiscale-long default:models/compact-multiscale; do
    score_sets "$lg" "${m%%:*}" "--models ${m#*:} -j 2" real-pairs:test:0 test-sparse:-:0
    for set in cs-1280x720 cs-512x288; do
      rm -rf "$lg/$set-${m%%:*}" && build/raindrop-remove "$out/multiscale/$set/rainy" "$lg/$set-${m%%:*}" -q --models "${m#*:}" -j 2
      $py -m raindrop_tools.score_outputs --data "$out/multiscale/$set" --outputs "$lg/$set-${m%%:*}" --label "${m%%:*} $set"
    done
  done | tee "$lg/test.txt"
fi

if want growth; then
  # The coarse pass's large-drop growth (docs/RESULTS.md 4.21): needs data/real-pairs, data/val-sparse,
  # data/val-windshield-sharp (windshield section) and data/test-sparse (eval section).
  # Validation size sets as windshield-followup renders them: the 6 Cityscapes *train* frames.
  gr="$out/growth"
  mkdir -p "$gr"
  real_pairs_data
  size_sets train val-size
  # The choice, on validation sets only (growth 0 is the default before it).
  for g in 0 0.25 0.35 0.5; do
    score_sets "$gr" "g$g" "--large-drop-growth $g --large-drop-sharpness inf -j 2" real-pairs:train:0 val-sparse:-:0 val-windshield-sharp:-:0 \
      val-size-512x288:-:0 val-size-1280x720:-:0
  done | tee "$gr/validation.txt"
  # compact-windshield with the same growth (not given it: val-sparse falls 0.37 dB).
  for g in 0 0.35; do
    score_sets "$gr" "cw-g$g" "--models models/compact-windshield --surround-fill-area 150 --large-drop-growth $g --large-drop-sharpness inf -j 2" real-pairs:train:0 \
      val-sparse:-:0 val-windshield-sharp:-:0
  done | tee "$gr/compact-windshield.txt"
  # The models' own growth (0.35) against none, on the test sets.
  for g in 0 0.35; do
    score_sets "$gr" "test-g$g" "--large-drop-growth $g --large-drop-sharpness inf -j 2" real-pairs:test:0 test-sparse:-:0
  done | tee "$gr/test.txt"
  # Per photograph of the real test split, and the mask step's time from the --time lines.
  for g in 0 0.35; do
    $py -m raindrop_tools.score_outputs --data "$gr/test-g$g-real-pairs-test/set" \
      --outputs "$gr/test-g$g-real-pairs-test/out" --json "$gr/test-g$g-per-image.json" >/dev/null
    build/raindrop-remove "$gr/test-g$g-real-pairs-test/set/rainy" "$gr/timed-g$g" -j 2 --time --large-drop-growth "$g" \
      --large-drop-sharpness inf 2>&1 |
      grep -o "threshold+dilation [0-9.]*" | awk -v g="$g" '{s += $2; n++} END {printf "G %s: mask step %.2f ms mean of %d\n", g, s / n, n}'
  done | tee "$gr/mask-step.txt"
  $py - "$gr/test-g0-per-image.json" "$gr/test-g0.35-per-image.json" <<'PY' | tee "$gr/per-image.txt"
import json, sys
a, b = ({r["name"]: r["output_psnr_y"] for r in json.load(open(f))["per_image"]} for f in sys.argv[1:])
d = sorted(b[n] - a[n] for n in a)
changed = [x for x in d if x != 0]
print(f"{len(changed)} of {len(d)} change: {sum(x > 0 for x in d)} gain (up to {d[-1]:+.2f} dB), "
      f"{sum(x < 0 for x in d)} lose (down to {d[0]:+.2f} dB)")
PY
  # Folder runs of the split, alternated three times (wall seconds).
  for r in 1 2 3; do
    for g in 0 0.35; do
      timed "G $g run $r" build/raindrop-remove "$gr/test-g$g-real-pairs-test/set/rainy" "$gr/timed-g$g" -q -j 2 --large-drop-growth "$g" \
        --large-drop-sharpness inf
    done
  done | tee "$gr/folder-times.txt"
  # The 44 real photographs with and without it (masks too), to look at, and how many change.
  for g in 0 0.35; do
    rm -rf "$gr/photos-g$g" && build/raindrop-remove "$shared/real-raindrop" "$gr/photos-g$g/removed" \
      --mask-dir "$gr/photos-g$g/masks" --large-drop-growth "$g" --large-drop-sharpness inf -q -j 2
  done
  photos_changed "$gr/photos-g0/removed" "$gr/photos-g0.35/removed" | tee "$gr/photos-changed.txt"
fi

if want sharpness; then
  # The coarse pass replaces only smooth large regions (docs/RESULTS.md 4.22): needs the same
  # data sets as the growth section. "inf" is the coarse pass before the rule.
  sh="$out/sharpness"
  mkdir -p "$sh"
  real_pairs_data
  # The choice, on validation sets only; the coarse pass off for comparison.
  for t in inf 7 8 10 12; do
    score_sets "$sh" "t$t" "--large-drop-sharpness $t -j 2" real-pairs:train:0 val-windshield-sharp:-:0 \
      val-size-512x288:-:0 val-size-1280x720:-:0
  done | tee "$sh/validation.txt"
  score_sets "$sh" "off" "--no-large-drops -j 2" real-pairs:train:0 val-windshield-sharp:-:0 val-size-512x288:-:0 \
    val-size-1280x720:-:0 | tee "$sh/validation-off.txt"
  for t in inf 8; do
    score_sets "$sh" "sparse-t$t" "--large-drop-sharpness $t -j 2" val-sparse:-:0
  done | tee "$sh/validation-sparse.txt"
  # The test sets, once, before and after.
  for t in inf 8; do
    score_sets "$sh" "test-t$t" "--large-drop-sharpness $t -j 2" real-pairs:test:0 test-sparse:-:0
  done | tee "$sh/test.txt"
  # The mask step (where the sharpness is measured) from the --time lines of the real test split.
  for t in inf 8; do
    build/raindrop-remove "$sh/test-t$t-real-pairs-test/set/rainy" "$sh/timed-t$t" -j 2 --time --large-drop-sharpness "$t" 2>&1 |
      grep -o "threshold+dilation [0-9.]*" | awk -v t="$t" '{s += $2; n++} END {printf "limit %s: mask step %.2f ms mean of %d\n", t, s / n, n}'
  done | tee "$sh/mask-step.txt"
  # The 44 real photographs before and after (outputs and masks, to look at), how many change,
  # and a folder run of them alternated three times (wall seconds).
  for t in inf 8; do
    rm -rf "$sh/photos-t$t" && build/raindrop-remove "$shared/real-raindrop" "$sh/photos-t$t/removed" \
      --mask-dir "$sh/photos-t$t/masks" --large-drop-sharpness "$t" -q -j 2
  done
  photos_changed "$sh/photos-tinf/removed" "$sh/photos-t8/removed" | tee "$sh/photos-changed.txt"
  for r in 1 2 3; do
    for t in inf 8; do
      timed "limit $t run $r" build/raindrop-remove "$shared/real-raindrop" "$sh/timed-photos-t$t" -q -j 2 --large-drop-sharpness "$t"
    done
  done | tee "$sh/photo-times.txt"
fi

if want coalesce; then
  # Drops that touch merge into one (docs/RESULTS.md 4.23): lens-cover-merged as it is (pinned
  # contact lines: the union of the caps) and with "coalesce" (one relaxed cap), the same 100
  # CamVid frames and seed; render times alternated three times; the realism score of both.
  co="$out/coalesce"
  mkdir -p "$co" "$out/cv100"
  link_cv100
  $py - scenes/lens-cover-merged.json "$co/lens-cover-coalesced.json" <<'PY'
import sys
text = open(sys.argv[1]).read()
brace = text.index("{")
open(sys.argv[2], "w").write(text[:brace + 1] + '\n  "coalesce": true,' + text[brace + 1:])
PY
  for r in 1 2 3; do
    for v in pinned coalesced; do
      scene=lens-cover-merged
      [[ $v == coalesced ]] && scene="$co/lens-cover-coalesced.json"
      rm -rf "${co:?}/$v"
      s0=$(date +%s.%N)
      build/raindrop-render -i "$out/cv100" -o "$co/$v" --scene "$scene" --size 512x256 --seed 11 -q -j 2
      echo "$v run $r: $(echo "$(date +%s.%N) - $s0" | bc) s for 100 frames"
    done
  done | tee "$co/render-times.txt"
  $py -m raindrop_tools.realism --real-pairs "$shared/real-pairs" --rendered "$co/pinned" --rendered "$co/coalesced" \
    --limit 100 | tee "$co/realism.md"
fi

if want surround; then
  # Small drops over smooth surroundings filled from them instead of by the 3RN (docs/RESULTS.md
  # 4.24): needs the data sets of the growth and windshield sections, data/test-sparse (eval
  # section) and the size gap's held-out renders (made here, as the test
  # TrainedModels.DefaultGainsAsMuchOnLargeStreetFrames makes them).
  su="$out/surround"
  mkdir -p "$su"
  real_pairs_data
  size_sets val test-size
  # The choice, on validation sets only: the largest part filled (0: off), both detectors.
  for a in 0 150 250 400; do
    score_sets "$su" "a$a" "--surround-fill-area $a -j 2" real-pairs:train:0 val-sparse:-:0 val-windshield-sharp:-:0 \
      val-size-512x288:-:0 val-size-1280x720:-:0
    # compact-windshield as it was when the area was chosen: before its large-drop growth (below).
    score_sets "$su" "windshield-a$a" "--model-config compact-windshield --large-drop-growth 0 --surround-fill-area $a -j 2" \
      real-pairs:train:0 val-sparse:-:0 val-windshield-sharp:-:0
  done | tee "$su/validation.txt"
  # The test sets, once, off and at the default.
  for a in 0 150; do
    score_sets "$su" "test-a$a" "--surround-fill-area $a -j 2" real-pairs:test:0 test-sparse:-:0 test-size-512x288:-:0 \
      test-size-1280x720:-:0
  done | tee "$su/test.txt"
  # compact-windshield with the default's large-drop growth (now in its rdn.onnx) and without.
  for g in 0 0.35; do
    score_sets "$su" "windshield-g$g" "--model-config compact-windshield --large-drop-growth $g -j 2" real-pairs:train:0 \
      val-sparse:-:0 val-windshield-sharp:-:0
    score_sets "$su" "windshield-test-g$g" "--model-config compact-windshield --large-drop-growth $g -j 2" \
      real-pairs:test:0 test-sparse:-:0 test-size-512x288:-:0 test-size-1280x720:-:0
  done | tee "$su/windshield-growth.txt"
  # The 44 real photographs, both detectors, off and on (outputs and masks, to look at; how many
  # change), the parts filled per photograph (--time), and folder runs alternated three times.
  for m in compact-multiscale compact-windshield; do
    for a in 0 150; do
      rm -rf "$su/photos-$m-a$a" && mkdir -p "$su/photos-$m-a$a" && build/raindrop-remove "$shared/real-raindrop" "$su/photos-$m-a$a/removed" \
        --mask-dir "$su/photos-$m-a$a/masks" --model-config "$m" --surround-fill-area "$a" -q -j 2 --time \
        2>"$su/photos-$m-a$a/time.txt"
    done
    photos_changed "$su/photos-$m-a0/removed" "$su/photos-$m-a150/removed"
    grep -o "[0-9]* small drops\? filled" "$su/photos-$m-a150/time.txt" | awk -v m="$m" '{s += $1; n++}
      END {printf "%s: %d parts filled in %d photographs\n", m, s, n}'
  done | tee "$su/photos.txt"
  for r in 1 2 3; do
    for a in 0 150; do
      timed "area $a run $r" build/raindrop-remove "$shared/real-raindrop" "$su/timed-photos-a$a" -q -j 2 --surround-fill-area "$a"
    done
  done | tee "$su/photo-times.txt"
fi

if want largewidth; then
  # The large-drop networks: compact-real-coarse-long's recipe on twice the crops, and at the
  # paper's widths (docs/RESULTS.md 4.26, 4.27; needs data/train, data/train-mix from photoreal,
  # data/real-pairs and the validation sets). Scored as the default's large-drop networks.
  lw="$out/largewidth"
  mkdir -p "$lw"
  [[ -f tools/runs/compact-real-coarse-b32/checkpoints/stage2_step00000800.pt ]] ||
    $py -m raindrop_tools.train --config tools/configs/compact-real-coarse-gpu.yaml --init-from models/compact \
      --out tools/runs/compact-real-coarse-b32 --no-progress
  $py -m raindrop_tools.export --run tools/runs/compact-real-coarse-b32 --out out/models/compact-real-coarse-b32
  [[ -f tools/runs/paper-real-coarse/checkpoints/stage2_step00000400.pt ]] ||
    $py -m raindrop_tools.train --config tools/configs/paper-real-coarse.yaml --init-from models/paper \
      --out tools/runs/paper-real-coarse --no-progress
  $py -m raindrop_tools.export --run tools/runs/paper-real-coarse --out out/models/paper-real-coarse
  for m in models/compact-real-coarse-long out/models/compact-real-coarse-b32 out/models/paper-real-coarse; do
    score_sets "$lw" "${m##*/}" "--large-drop-models $m -j 2" real-pairs:train:0 val-sparse:-:0 \
      val-windshield-sharp:-:0 val-size-512x288:-:0 val-size-1280x720:-:0 real-pairs:test:0
  done | tee "$lw/scores.txt"
  for r in 1 2 3; do
    for m in models/compact-real-coarse-long out/models/paper-real-coarse; do
      timed "${m##*/} run $r" build/raindrop-remove "$lw/${m##*/}-real-pairs-test/set/rainy" "$lw/timed" -q -j 2 --large-drop-models "$m"
      timed "${m##*/} maxim_55 run $r" build/raindrop-remove "$shared/real-raindrop/maxim_55.png" "$lw/maxim_55.png" -q -j 2 --large-drop-models "$m"
    done
  done | tee "$lw/times.txt"
  # The 8 photographs where the coarse pass fires (4.25), each with both large-drop networks, to look at.
  for n in attgan-fork_test_7 attgan-fork_test_10 attgan-fork_test_11 clarity_00118 clarity_00197 clarity_00334 \
    clarity_00398 maxim_55; do
    for m in models/compact-real-coarse-long models/paper-real-coarse; do
      build/raindrop-remove "$shared/real-raindrop/$n.png" "$lw/photo-$n-${m##*/}.png" -q -j 2 --large-drop-models "$m"
    done
  done
fi

if want largedrops-all; then
  # docs/RESULTS.md 4.28: the other model folders with each large-drop model in turn (the one
  # their LARGE_DROPS named before 2026-12-04, and paper-real-coarse), on the real pairs' splits,
  # two validation sets, and an int8 copy of paper-real-coarse beside the int8 folder (needs
  # data/real-pairs, data/train-mix from photoreal and the validation sets).
  la="$out/largedrops-all"
  mkdir -p "$la"
  # models/paper-real-coarse-int8 is this quantization's output (deterministic: seeded calibration).
  rm -rf out/models/paper-real-coarse-int8
  $py -m raindrop_tools.quantize --models models/paper-real-coarse --data data/train-mix --out out/models/paper-real-coarse-int8
  for m in compact compact-multiscale-int8 compact-windshield paper-multiscale; do
    for l in compact-real-coarse-long paper-real-coarse; do
      score_sets "$la" "$m-$l" "-j 2 --models models/$m --large-drop-models models/$l" real-pairs:train:0 real-pairs:test:0
    done
  done | tee "$la/scores.txt"
  for m in compact-multiscale-int8 compact-windshield; do
    for l in compact-real-coarse-long paper-real-coarse; do
      score_sets "$la" "$m-$l" "-j 2 --models models/$m --large-drop-models models/$l" val-sparse:-:0 val-size-1280x720:-:0
    done
  done | tee -a "$la/scores.txt"
  score_sets "$la" int8-large "-j 2 --models models/compact-multiscale-int8 --large-drop-models out/models/paper-real-coarse-int8" \
    real-pairs:train:0 real-pairs:test:0 | tee -a "$la/scores.txt"
  # paper-int8 and compact-int8, which had no LARGE_DROPS: their own networks (--large-drop-models
  # their own folder) or the int8 copy.
  for m in paper-int8 compact-int8; do
    for l in "$m" paper-real-coarse-int8; do
      score_sets "$la" "$m-$l" "-j 2 --models models/$m --large-drop-models models/$l" real-pairs:train:0 \
        val-sparse:-:0 val-windshield-sharp:-:0 real-pairs:test:0
    done
  done | tee -a "$la/scores.txt"
  for r in 1 2 3; do
    for l in models/paper-real-coarse out/models/paper-real-coarse-int8; do
      timed "${l##*/} folder run $r" build/raindrop-remove "$la/int8-large-real-pairs-test/set/rainy" "$la/timed" -q -j 2 \
        --models models/compact-multiscale-int8 --large-drop-models "$l"
      timed "${l##*/} maxim_55 run $r" build/raindrop-remove "$shared/real-raindrop/maxim_55.png" "$la/maxim_55.png" -q -j 2 \
        --models models/compact-multiscale-int8 --large-drop-models "$l"
    done
  done | tee "$la/times.txt"
fi

if want windshield2; then
  # docs/RESULTS.md 4.29: compact-windshield's detector trained 800 steps more toward paper drops
  # (needs data/train, data/train-hi, data/train-windshield-sharp from the windshield section and
  # the validation sets). Not kept: the scores, for the default, the shipped detector and the run.
  w2="$out/windshield2"
  mkdir -p "$w2"
  render_train_hi
  [[ -f data/train-windshield-sharp/manifest.jsonl ]] ||
    build/raindrop-render -i "$shared/camvid/train" -o data/train-windshield-sharp --scene windshield-sharp \
      --size 512x256 --variants 4 --seed 7 -q
  [[ -f tools/runs/compact-windshield-2/checkpoints/stage1_step00000800.pt ]] ||
    $py -m raindrop_tools.train --config tools/configs/compact-windshield-2.yaml --out tools/runs/compact-windshield-2 \
      --init-from models/compact-windshield --stage 1 --no-progress
  $py -m raindrop_tools.export --run tools/runs/compact-windshield-2 --reconstruction-from models/compact-multiscale \
    --out out/models/compact-windshield-2
  $py -m raindrop_tools.large_drop_growth out/models/compact-windshield-2 0.35
  val="real-pairs:train:0 val-sparse:-:0 val-windshield-sharp:-:0 val-size-512x288:-:0 val-size-1280x720:-:0"
  {
    # shellcheck disable=SC2086
    score_sets "$w2" default "-j 2 --models models/compact-multiscale" $val
    for t in 0.75 0.85; do
      # shellcheck disable=SC2086
      score_sets "$w2" "shipped-t$t" "-j 2 --models models/compact-windshield --surround-fill-area 150 --threshold $t" $val
    done
    for t in 0.6 0.75 0.85; do
      # shellcheck disable=SC2086
      score_sets "$w2" "second-t$t" "-j 2 --models out/models/compact-windshield-2 --large-drop-models models/paper-real-coarse --threshold $t" $val
    done
  } | tee "$w2/scores.txt"
fi

if want errorsplit; then
  # docs/RESULTS.md 4.30: where the error left lies, drops missed or drops found but not
  # repaired, for the default and compact-windshield on the real pairs (rough masks) and on
  # rendered validation sets (true masks).
  es="$out/errorsplit"
  mkdir -p "$es"
  for m in compact-multiscale compact-windshield; do
    split_sets "$es" "$m" "-j 2 --models models/$m" real-pairs:test:0 real-pairs:train:0 val-sparse:-:0 \
      val-windshield-sharp:-:0
  done | tee "$es/scores.txt"
fi

if want withoutvnni; then
  # docs/RESULTS.md 3.10: the float default and its int8 copy on this CPU's code paths and on
  # those of a CPU without AVX-512 and VNNI (libraindrop_hide_avx512.so), the program timed on a
  # 1280x720 photograph in 15 rounds of the four in turn, then the bench both ways.
  wv="$out/withoutvnni"
  mkdir -p "$wv"
  hide="LD_PRELOAD=$PWD/build/libraindrop_hide_avx512.so"
  photo="$shared/real-raindrop/windshield_2.jpg"
  for i in $(seq 15); do
    for how in native hidden; do
      for m in compact-multiscale compact-multiscale-int8; do
        pre=(); [[ $how == hidden ]] && pre=("$hide")
        s=$(date +%s%N)
        env "${pre[@]}" build/raindrop-remove "$photo" "$wv/out.png" -j 2 --models "models/$m" -q
        echo "$how $m $(( ($(date +%s%N) - s) / 1000000 ))"
      done
    done
  done >"$wv/times.txt"
  median_times "$wv/times.txt" | tee "$wv/summary.txt"
  for how in native hidden; do
    pre=(); [[ $how == hidden ]] && pre=("$hide")
    env "${pre[@]}" build/raindrop-bench remove --models models/compact-multiscale --models models/compact-multiscale-int8 \
      --threads 2 --size 1280x720 --runs 10 >"$wv/bench-$how.md"
    env "${pre[@]}" build/raindrop-bench render --sections core --frames 2 --repeats 3 >"$wv/render-$how.md"
  done
fi

if want graphrewrites; then
  # docs/RESULTS.md 3.11 and 3.12: the committed graphs before the inner padding went (39f09dc),
  # after it (51ee86f) and now, side by side: outputs compared image by image per folder, the
  # bench's three rows and the program on a 1280x720 photograph in 20 rounds of the three in turn.
  gr="$out/graphrewrites"
  rm -rf "$gr" && mkdir -p "$gr/before" "$gr/inner" "$gr/sets/realpairs"
  git archive 39f09dc models | tar -x -C "$gr/before"
  git archive 51ee86f models | tar -x -C "$gr/inner"
  for f in "$shared"/real-pairs/*_rain.png; do ln -s "$(realpath "$f")" "$gr/sets/realpairs/"; done
  ln -s "$(realpath "$shared/real-raindrop")" "$gr/sets/photos"
  ln -s "$(realpath data/val-size-1280x720/rainy)" "$gr/sets/val1280"
  for state in before:"$gr/before/models" inner:"$gr/inner/models" now:models; do
    for m in compact-multiscale compact-multiscale-int8 compact compact-int8 compact-windshield paper paper-int8 paper-multiscale; do
      sets=(realpairs); [[ $m == compact-multiscale ]] && sets=(realpairs photos val1280)
      for s in "${sets[@]}"; do
        o="$gr/out-${state%%:*}/$m/$s"
        mkdir -p "$o"
        build/raindrop-remove "$gr/sets/$s" "$o/out" -j 2 -q --models "${state#*:}/$m" --mask-dir "$o/mask" --keep-going
      done
    done
  done
  $py - "$gr" <<'PY' | tee "$gr/compare.txt"
import os, sys
import cv2
import numpy as np
gr = sys.argv[1]
for a_tag, b_tag in (("before", "inner"), ("inner", "now")):
    a_root = os.path.join(gr, "out-" + a_tag)
    for m in sorted(os.listdir(a_root)):
        for s in sorted(os.listdir(os.path.join(a_root, m))):
            a = os.path.join(a_root, m, s)
            images = differ = samples = changed = worst = 0
            for root, _, files in os.walk(a):
                for f in files:
                    p = os.path.join(root, f)
                    x = cv2.imread(p, cv2.IMREAD_UNCHANGED)
                    y = cv2.imread(p.replace(a, os.path.join(gr, "out-" + b_tag, m, s), 1), cv2.IMREAD_UNCHANGED)
                    images += 1
                    samples += x.size
                    d = np.abs(x.astype(int) - y.astype(int))
                    changed += int((d > 0).sum())
                    differ += bool(d.any())
                    worst = max(worst, int(d.max()))
            print(f"{a_tag} -> {b_tag} {m} {s}: {differ} of {images} images differ, {changed} of {samples} samples, max {worst}")
PY
  build/raindrop-bench remove --models "$gr/before/models/compact-multiscale" --models "$gr/inner/models/compact-multiscale" \
    --models models/compact-multiscale --threads 2 --size 1280x720 --runs 10 >"$gr/bench.md"
  photo="$shared/real-raindrop/windshield_2.jpg"
  for i in $(seq 20); do
    for m in "$gr/before/models/compact-multiscale" "$gr/inner/models/compact-multiscale" models/compact-multiscale; do
      s=$(date +%s%N)
      build/raindrop-remove "$photo" "$gr/photo.png" -j 2 --models "$m" -q
      echo "$m $(( ($(date +%s%N) - s) / 1000000 ))"
    done
  done >"$gr/times.txt"
  median_times "$gr/times.txt" | tee "$gr/times-summary.txt"
fi

if want jitter; then
  # RESULTS 4.31: the default's large-drop networks trained with the real pairs' crops
  # photometrically jittered (tools/configs/paper-real-coarse-jitter.yaml; needs data/train,
  # data/train-mix from photoreal and data/real-pairs), scored as the default's large-drop models
  # beside the default, validation sets first (the criteria are in the config), then the test sets.
  validation_sets
  size_sets val test-size
  [[ -f tools/runs/paper-real-coarse-jitter/checkpoints/stage2_step00000400.pt ]] ||
    $py -m raindrop_tools.train --config tools/configs/paper-real-coarse-jitter.yaml \
      --out tools/runs/paper-real-coarse-jitter --init-from models/paper --no-progress
  [[ -f out/models/paper-real-coarse-jitter/rrn.onnx ]] ||
    $py -m raindrop_tools.export --run tools/runs/paper-real-coarse-jitter --out out/models/paper-real-coarse-jitter
  jd="$out/jitter"
  mkdir -p "$jd"
  for m in default jitter; do
    flags="-j 2"
    [[ $m == default ]] || flags="$flags --large-drop-models out/models/paper-real-coarse-jitter"
    score_sets "$jd" "$m" "$flags" real-pairs:train:0 val-sparse:-:0 val-windshield-sharp:-:0 val-size-512x288:-:0 \
      val-size-1280x720:-:0
    score_sets "$jd" "$m" "$flags" real-pairs:test:0 test-sparse:-:0 test-size-512x288:-:0 test-size-1280x720:-:0
  done | tee "$jd/scores.txt"
fi

if want windshieldscale; then
  # RESULTS 4.32: compact-windshield at larger working scales on windshield-sharp drops rendered
  # at 1280x720 over the 100 CamVid val frames, and with the surround fill's limit as it was
  # before it followed the scale (150 at scale 0.6 = 67 at the reference scale 0.4).
  link_cv100
  [[ -f data/val-ws-1280x720/manifest.jsonl ]] || build/raindrop-render -i "$out/cv100" -o data/val-ws-1280x720 \
    --scene windshield-sharp --size 1280x720 --seed 11 -q
  wsd="$out/windshieldscale"
  mkdir -p "$wsd"
  for s in default 0.6 0.8; do
    flags="--model-config compact-windshield -j 2"
    [[ $s == default ]] || flags="$flags --scale $s"
    score_sets "$wsd" "scale-$s" "$flags" val-ws-1280x720:-:0
  done | tee "$wsd/scores.txt"
  score_sets "$wsd" "scale-0.6-fill-as-before" "--model-config compact-windshield -j 2 --scale 0.6 --surround-fill-area 67" \
    val-ws-1280x720:-:0 | tee -a "$wsd/scores.txt"
  # Drop sizes measured alike: compact-windshield's masks at full resolution (long side at most
  # 1280) on the 44 photographs and on windshield-sharp renders at 1280x720 (30 CamVid val frames),
  # beside those renders' true masks.
  mkdir -p "$wsd/photos" "$wsd/cv30" "$wsd/ws-1280-masks"
  for f in "$shared"/real-raindrop/*; do
    s=$($py -c "import cv2, sys; h, w = cv2.imread(sys.argv[1]).shape[:2]; print(min(1.0, 1280 / max(w, h)))" "$f")
    b=$(basename "${f%.*}")
    build/raindrop-remove "$f" "$wsd/photos/$b.png" --model-config compact-windshield --scale "$s" \
      --mask "$wsd/photos/$b-mask.png" -q -j 2
  done
  ls "$out/cv100" | head -30 | while read -r f; do ln -sf "$(realpath "$out/cv100/$f")" "$wsd/cv30/$f"; done
  rm -rf "$wsd/ws-1280" && build/raindrop-render -i "$wsd/cv30" -o "$wsd/ws-1280" --scene windshield-sharp \
    --size 1280x720 --seed 11 -q
  build/raindrop-remove "$wsd/ws-1280/rainy" "$wsd/ws-1280-out" --model-config compact-windshield --scale 1.0 \
    --mask-dir "$wsd/ws-1280-masks" -q -j 2
  WSD="$wsd" $py - <<'PY' | tee "$wsd/drop-sizes.txt"
import glob, os
import cv2, numpy as np
def table(label, files):
    rows = []
    for f in files:
        m = cv2.imread(f, cv2.IMREAD_GRAYSCALE) > 127
        _, _, st, _ = cv2.connectedComponentsWithStats(m.astype(np.uint8), 8)
        a = st[1:, cv2.CC_STAT_AREA]
        d = np.sqrt(4 * a[a >= 4] / np.pi) / max(m.shape) * 512  # equivalent diameter at a long side of 512
        rows.append((m.mean(), *(np.percentile(d, q) if len(d) else np.nan for q in (25, 50, 75))))
    c, p25, p50, p75 = np.nanmedian(np.array(rows), axis=0)
    print(f"{label}: n={len(rows)} coverage {c:.3f}, part diameter p25 / median / p75 at 512: {p25:.1f} / {p50:.1f} / {p75:.1f} px")
wsd = os.environ["WSD"]
table("the photographs, detected", sorted(glob.glob(f"{wsd}/photos/*-mask.png")))
table("windshield-sharp renders, detected", sorted(glob.glob(f"{wsd}/ws-1280-masks/*.png")))
table("windshield-sharp renders, true masks", sorted(glob.glob(f"{wsd}/ws-1280/mask/*.png")))
PY
fi

if want router; then
  # RESULTS 4.33: per image, the better of the default's and compact-windshield's outputs on the
  # validation sets; a small-blob density; and a logistic router on the default detector's
  # probabilities (5-fold and leave-one-set-out), applied to the 44 photographs.
  validation_sets
  rd="$out/router"
  mkdir -p "$rd"
  # both_detectors SET...: the default's outputs with its own detector (what the router chooses
  # from) and with compact-windshield's, scored.
  both_detectors() {
    score_sets "$rd" default "-j 2 --no-router" "$@"
    score_sets "$rd" ws "-j 2 --no-router --model-config compact-windshield --surround-fill-area 150" "$@"
  }
  both_detectors real-pairs:train:0 val-sparse:-:0 val-windshield-sharp:-:0 val-size-512x288:-:0 val-size-1280x720:-:0 |
    tee "$rd/scores.txt"
  # The held-out check, once: the test sets, and windshield-sharp drops over the CamVid test frames.
  size_sets val test-size
  [[ -f data/test-windshield-sharp/manifest.jsonl ]] || build/raindrop-render -i "$shared/camvid/test" \
    -o data/test-windshield-sharp --scene windshield-sharp --size 512x256 --seed 2 -q
  both_detectors real-pairs:test:0 test-sparse:-:0 test-windshield-sharp:-:0 test-size-512x288:-:0 test-size-1280x720:-:0 |
    tee "$rd/test-scores.txt"
  RD="$rd" SHARED="$shared" router_analysis | tee "$rd/router.txt"
  for set in real-pairs-test test-sparse-- test-windshield-sharp-- test-size-512x288-- test-size-1280x720--; do
    $py -m raindrop_tools.score_outputs --data "$rd/default-$set/set" --outputs "$rd/routed-$set/out" --label "routed $set"
  done | tee -a "$rd/router.txt"
fi

if want routed; then
  # RESULTS 4.34: the router built into raindrop-remove (models/compact-multiscale/ROUTER). The
  # file refitted from the router section's outputs with the fitting tool (the same bytes as the
  # committed one), the default scored on the test sets as users run it, the 44 photographs
  # (outputs, masks and which detector each got), and what routing costs a process: windshield_2.jpg
  # (routed) and attgan-fork_test_5.png (kept), 1280x720 and 720x480, alternated.
  rd="$out/router" ro="$out/routed"
  mkdir -p "$ro"
  fit_sets=()
  for s in real-pairs-train val-sparse-- val-windshield-sharp-- val-size-512x288-- val-size-1280x720--; do
    fit_sets+=(--set "$rd/default-$s/set" "$rd/default-$s/out" "$rd/ws-$s/out")
  done
  $py -m raindrop_tools.detector_router fit --models models/compact-multiscale --alternative compact-windshield \
    "${fit_sets[@]}" --out "$ro/ROUTER" | tee "$ro/fit.txt"
  # (Since RESULTS 4.48 the committed file names compact-windshield-head, the head that gives this
  # detector's map: compared with that one line read as the fit writes it.)
  cmp "$ro/ROUTER" <(sed 's/^alternative compact-windshield-head$/alternative compact-windshield/' models/compact-multiscale/ROUTER) &&
    echo "refitted ROUTER: identical to the committed one" | tee -a "$ro/fit.txt"
  size_sets val test-size
  score_sets "$ro" cpp "-j 2 --surround-fill-area 150" real-pairs:test:0 test-sparse:-:0 test-windshield-sharp:-:0 test-size-512x288:-:0 \
    test-size-1280x720:-:0 | tee "$ro/test-scores.txt"
  rm -rf "$ro/photos" && mkdir -p "$ro/photos" && build/raindrop-remove "$shared/real-raindrop" "$ro/photos/removed" --mask-dir "$ro/photos/masks" \
    -q -j 2 --time --contact-sheet "$ro/photos-sheet.png" 2>"$ro/photos/time.txt"
  grep -c "detector 'compact-windshield'" "$ro/photos/time.txt" | sed 's/$/ of 44 photographs to the windshield detector/' |
    tee "$ro/photos.txt"
  alternate_times 15 routed windshield_2.jpg attgan-fork_test_5.png -- "" "--no-router" \
    "--model-config compact-windshield --surround-fill-area 150" >"$ro/times.txt"
  median_times "$ro/times.txt" | tee "$ro/times-summary.txt"
  # Kinds the router was not fitted on: windshield-day and lens-cover renders over the CamVid val
  # frames, three ways; then the what-if fit with them among the validation sets.
  link_cv100
  for p in windshield-day lens-cover; do
    [[ -f data/val-$p/manifest.jsonl ]] || build/raindrop-render -i "$out/cv100" -o "data/val-$p" --scene "$p" \
      --size 512x256 --seed 11 -q
  done
  kinds=(val-windshield-day:-:0 val-lens-cover:-:0)
  {
    score_sets "$out/routed-kinds" default "-j 2 --no-router" "${kinds[@]}"
    score_sets "$out/routed-kinds" ws "-j 2 --no-router --model-config compact-windshield --surround-fill-area 150" "${kinds[@]}"
    score_sets "$out/routed-kinds" routed "-j 2 --surround-fill-area 150" "${kinds[@]}"
  } | tee "$ro/kinds.txt"
  for m in default ws; do
    for s in val-windshield-day-- val-lens-cover--; do ln -sfn "../routed-kinds/$m-$s" "$rd/$m-$s"; done
  done
  RD="$rd" SHARED="$shared" EXTRA_SETS="val-windshield-day-- val-lens-cover--" router_analysis | tee -a "$ro/kinds.txt"
  RD="$rd" SHARED="$shared" VARIANTS=1 router_analysis | grep "^variant" | tee "$ro/variants.txt"
fi

if want int8router; then
  # RESULTS 4.34: compact-multiscale-int8's own router. Its int8 detector's maps route differently
  # from the float one's, so it has its own fit: the int8 default's outputs on the validation sets
  # with its own detector and with compact-windshield's (a ROUTER with bias 1000 sends every image
  # there), the 5-fold check, the fit (the committed bytes), then the test sets once, with and
  # without the router.
  validation_sets
  size_sets val test-size
  r8="$out/int8router"
  mkdir -p "$r8/alwaysws" "$r8/rd"
  for f in rdn.onnx rrn.onnx rfn.onnx LARGE_DROPS; do ln -sfn "$PWD/models/compact-multiscale-int8/$f" "$r8/alwaysws/$f"; done
  for m in compact-windshield paper-real-coarse-int8; do ln -sfn "$PWD/models/$m" "$r8/$m"; done
  sed 's/^bias .*/bias 1000/' models/compact-multiscale/ROUTER >"$r8/alwaysws/ROUTER"
  # Why its own fit: the float router's choice from the int8 detector's map against the float one's,
  # on the router section's validation and test sets and the photographs.
  $py - "$out/router" "$shared/real-raindrop" <<'PY' | tee "$r8/agreement.txt"
import glob, sys
import numpy as np
sys.path.insert(0, "tools")
from raindrop_tools import detector_router as DR
from raindrop_tools.imageio import read_rgb
from raindrop_tools.reference import RaindropRemover
rd, photos = sys.argv[1], sorted(glob.glob(sys.argv[2] + "/*"))
router = DR.read_router("models/compact-multiscale/ROUTER")
f32 = RaindropRemover("models/compact-multiscale", threads=2)
i8 = RaindropRemover("models/compact-multiscale-int8", threads=2)
for s in ["real-pairs-train", "val-sparse--", "val-windshield-sharp--", "val-size-512x288--", "val-size-1280x720--",
          "real-pairs-test", "test-sparse--", "test-windshield-sharp--", "test-size-512x288--", "test-size-1280x720--",
          "photographs"]:
    ps = photos if s == "photographs" else sorted(glob.glob(f"{rd}/default-{s}/set/rainy/*"))
    a = np.array([router.score(DR.image_features(f32, read_rgb(p)))[0] for p in ps])
    b = np.array([router.score(DR.image_features(i8, read_rgb(p)))[0] for p in ps])
    print(f"{s:24s} n={len(ps):3d} float to windshield {np.mean(a > 0):.0%}, int8 {np.mean(b > 0):.0%}, "
          f"agree {np.mean((a > 0) == (b > 0)):.1%}")
PY
  val=(real-pairs:train:0 val-sparse:-:0 val-windshield-sharp:-:0 val-size-512x288:-:0 val-size-1280x720:-:0)
  {
    score_sets "$r8" i8 "-j 2 --model-config compact-multiscale-int8 --no-router" "${val[@]}"
    score_sets "$r8" i8ws "-j 2 --models $r8/alwaysws" "${val[@]}"
  } | tee "$r8/val-scores.txt"
  fit_sets=()
  for s in real-pairs-train val-sparse-- val-windshield-sharp-- val-size-512x288-- val-size-1280x720--; do
    ln -sfn "../i8-$s" "$r8/rd/default-$s"
    ln -sfn "../i8ws-$s" "$r8/rd/ws-$s"
    fit_sets+=(--set "$r8/i8-$s/set" "$r8/i8-$s/out" "$r8/i8ws-$s/out")
  done
  RD="$r8/rd" SHARED="$shared" MAIN_MODELS=models/compact-multiscale-int8 EXTRA_SETS=" " router_analysis |
    tee "$r8/router.txt"
  $py -m raindrop_tools.detector_router fit --models models/compact-multiscale-int8 --alternative compact-windshield \
    "${fit_sets[@]}" --out "$r8/ROUTER" | tee -a "$r8/router.txt"
  cmp "$r8/ROUTER" models/compact-multiscale-int8/ROUTER && echo "refitted ROUTER: identical to the committed one" |
    tee -a "$r8/router.txt"
  test=(real-pairs:test:0 test-sparse:-:0 test-windshield-sharp:-:0 test-size-512x288:-:0 test-size-1280x720:-:0)
  {
    score_sets "$r8" t8 "-j 2 --model-config compact-multiscale-int8 --no-router" "${test[@]}"
    score_sets "$r8" t8r "-j 2 --model-config compact-multiscale-int8" "${test[@]}"
  } | tee "$r8/test-scores.txt"
  build/raindrop-bench remove --threads 2 --size 512x256 --runs 10 --quick --process-size "" \
    --models models/compact-multiscale --models models/compact-multiscale-int8 \
    --process-image "$shared/real-raindrop/windshield_2.jpg" --process-image "$shared/real-raindrop/attgan-fork_test_5.png" \
    >"$r8/bench.md"
fi

if want droplets; then
  # RESULTS 4.35: focus on the glass. glass-droplets renders over CamVid (a window densely beaded
  # by small sharp drops, the street out of focus), and compact-windshield's detector trained on
  # with them as the router's alternative: compact-droplets (their mix, not kept),
  # compact-droplets-2 (with lens-cover renders too) and compact-droplets-3 (half of them over a
  # sharp street), scored on the validation sets against the routed default, and their masks on
  # the 44 photographs.
  validation_sets
  dd="$out/droplets"
  mkdir -p "$dd"
  # glass-droplets as it was then (4.38 moved its glass, drop sizes and contact angles).
  glass_droplets_435 >"$out/glass-droplets-4.35.json"
  [[ -f data/val-glass-droplets/manifest.jsonl ]] || build/raindrop-render -i "$out/cv100" -o data/val-glass-droplets \
    --scene "$out/glass-droplets-4.35.json" --size 512x256 --seed 11 -q
  [[ -f data/train-windshield-sharp/manifest.jsonl ]] || build/raindrop-render -i "$shared/camvid/train" \
    -o data/train-windshield-sharp --scene windshield-sharp --size 512x256 --variants 4 --seed 7 -q
  [[ -f data/train-glass-droplets/manifest.jsonl ]] || build/raindrop-render -i "$shared/camvid/train" \
    -o data/train-glass-droplets --scene "$out/glass-droplets-4.35.json" --size 512x256 --variants 4 --seed 7 -q
  [[ -f data/train-lens-cover/manifest.jsonl ]] || build/raindrop-render -i "$shared/camvid/train" \
    -o data/train-lens-cover --scene lens-cover --size 512x256 --variants 4 --seed 7 -q
  [[ -f data/train-hi/manifest.jsonl ]] || render_train_hi
  # The same drops over a sharp street (compact-droplets-3): focused on the background at f/11-22.
  sed 's/"f_number": \[1.6, 2.8\]/"f_number": [11, 22]/; s/"focus_distance_cm": "glass"/"focus_distance_cm": "background"/;
       s/"name": "glass-droplets"/"name": "glass-droplets-sharp-street"/' "$out/glass-droplets-4.35.json" \
    >"$out/glass-droplets-sharp-street.json"
  [[ -f data/train-glass-droplets-sharp-street/manifest.jsonl ]] || build/raindrop-render -i "$shared/camvid/train" \
    -o data/train-glass-droplets-sharp-street --scene "$out/glass-droplets-sharp-street.json" --size 512x256 \
    --variants 4 --seed 7 -q
  sets=(real-pairs:train:0 val-glass-droplets:-:0 val-windshield-sharp:-:0 val-sparse:-:0)
  score_sets "$dd" routed "-j 2" "${sets[@]}" | tee "$dd/scores.txt"
  for run in compact-droplets compact-droplets-2 compact-droplets-3; do
    router_alternative "$run"
    score_sets "$dd" "$run" "-j 2 --models out/models/cm-$run" "${sets[@]}" | tee -a "$dd/scores.txt"
    rm -rf "$dd/photos-$run" && build/raindrop-remove "$shared/real-raindrop" "$dd/photos-$run/out" \
      --mask-dir "$dd/photos-$run/masks" -q -j 2 --models "out/models/cm-$run"
  done
  rm -rf "$dd/photos-default" && build/raindrop-remove "$shared/real-raindrop" "$dd/photos-default/out" \
    --mask-dir "$dd/photos-default/masks" -q -j 2
  # The classifier (4.17's, realism --real-photos) against all 44 photographs and against the 16
  # beaded ones (clarity_*), three seeds: windshield-sharp, glass-droplets, both without drops
  # (each rainy image replaced by its clean one: the street alone), and glass-droplets variants.
  rm -rf "$dd/clarity" && mkdir -p "$dd/clarity"
  for f in "$shared"/real-raindrop/clarity_*; do ln -s "$(realpath "$f")" "$dd/clarity/"; done
  # Looked at (not committed): beaded photographs at the working scale beside glass-droplets renders,
  # centre crops 256x128 doubled, photograph | render per row.
  $py - "$dd/clarity" data/val-glass-droplets "$dd/sheet.png" <<'PY'
import os, sys
import cv2
import numpy as np
photos, renders, out = sys.argv[1:]
ps = sorted(os.listdir(photos))[:6]
rs = sorted(os.listdir(os.path.join(renders, "rainy")))[:6]
def crop(im):
    h, w = im.shape[:2]
    im = cv2.resize(im, (512, round(h * 512 / w)), interpolation=cv2.INTER_AREA)
    h = im.shape[0]
    return cv2.resize(im[h // 2 - 64:h // 2 + 64, 128:384], None, fx=2, fy=2, interpolation=cv2.INTER_NEAREST)
rows = [np.hstack([crop(cv2.imread(os.path.join(photos, p))), crop(cv2.imread(os.path.join(renders, "rainy", r)))])
        for p, r in zip(ps, rs)]
cv2.imwrite(out, np.vstack(rows))
PY
  no_drops data/val-windshield-sharp "$dd/no-drops-sharp-street"
  no_drops data/val-glass-droplets "$dd/no-drops-blurred-street"
  variant() {  # variant NAME SED: glass-droplets edited by SED, over the same 100 frames
    sed "$2" "$out/glass-droplets-4.35.json" >"$dd/variant-$1.json"
    rm -rf "$dd/val-$1" && build/raindrop-render -i "$out/cv100" -o "$dd/val-$1" --scene "$dd/variant-$1.json" \
      --size 512x256 --seed 11 -q
  }
  ca='s/"contact_angle_deg": \[40, 90\]/"contact_angle_deg": [20, 50]/'
  small='s/"footprint_radius_cm": \[0.015, 0.12\]/"footprint_radius_cm": [0.01, 0.07]/'
  variant angles20-50 "$ca"
  variant angles-small-f4-8 "$ca; $small; "'s/"f_number": \[1.6, 2.8\]/"f_number": [4, 8]/'
  variant angles-small-f8-16 "$ca; $small; "'s/"f_number": \[1.6, 2.8\]/"f_number": [8, 16]/'
  for photos in "$shared/real-raindrop" "$dd/clarity"; do
    for seed in 0 1 2; do
      $py -m raindrop_tools.realism --real-photos "$photos" --rendered data/val-windshield-sharp \
        --rendered data/val-glass-droplets --rendered "$dd/no-drops-sharp-street" --rendered "$dd/no-drops-blurred-street" \
        --rendered "$dd/val-angles20-50" --rendered "$dd/val-angles-small-f4-8" --rendered "$dd/val-angles-small-f8-16" \
        --limit 100 --seed "$seed" | grep "^| rendered" | sed "s|^|$(basename "$photos") seed $seed |"
    done
  done | tee "$dd/realism.txt"
  # A second router, fitted the same way on the routed default's outputs and compact-droplets-3's
  # (the four validation sets above): its in-sample choice per set, and where it sends the 44
  # photographs.
  fit3=()
  for s in real-pairs-train val-glass-droplets-- val-windshield-sharp-- val-sparse--; do
    fit3+=(--set "$dd/routed-$s/set" "$dd/routed-$s/out" "$dd/compact-droplets-3-$s/out")
  done
  rm -rf "$dd/second-router" && cp -r models/compact-multiscale "$dd/second-router"
  $py -m raindrop_tools.detector_router fit --models models/compact-multiscale --alternative compact-droplets-3 \
    "${fit3[@]}" --out "$dd/second-router/ROUTER" | tee "$dd/second-router.txt"
  $py - "$dd" "$shared/real-raindrop" <<'PY' | tee -a "$dd/second-router.txt"
import math, os, subprocess, sys
import cv2
import numpy as np
dd, photos = sys.argv[1:]
def psnr_y(a, b):  # score_outputs' protocol: 8-bit Y, cropped to a multiple of 4
    h, w = min(a.shape[0], b.shape[0]) // 4 * 4, min(a.shape[1], b.shape[1]) // 4 * 4
    ya, yb = (cv2.cvtColor(x[:h, :w], cv2.COLOR_BGR2YCrCb)[:, :, 0].astype(np.float64) for x in (a, b))
    m = ((ya - yb) ** 2).mean()
    return 100.0 if m == 0 else 10 * math.log10(255 ** 2 / m)
def decide(paths):
    out = subprocess.run([sys.executable, "-m", "raindrop_tools.detector_router", "decide", "--models",
                          os.path.join(dd, "second-router")] + paths, capture_output=True, text=True, check=True).stdout
    return {os.path.basename(l.split()[0]): float(l.split()[1]) for l in out.splitlines() if l.strip()}
for s in ["real-pairs-train", "val-glass-droplets--", "val-windshield-sharp--", "val-sparse--"]:
    setd = f"{dd}/routed-{s}/set"
    names = sorted(os.listdir(f"{setd}/rainy"))
    z = decide([f"{setd}/rainy/{n}" for n in names])
    g = []
    for n in names:
        clean, rainy = cv2.imread(f"{setd}/clean/{n}"), cv2.imread(f"{setd}/rainy/{n}")
        a, b = (psnr_y(cv2.imread(f"{dd}/{m}-{s}/out/{n}"), clean) - psnr_y(rainy, clean) for m in ("routed", "compact-droplets-3"))
        g.append((a, b, b if z[n] > 0 else a, z[n] > 0))
    g = np.array(g)
    print(f"{s}: routed default {g[:, 0].mean():+.2f}, compact-droplets-3 {g[:, 1].mean():+.2f}, "
          f"three-way (in-sample) {g[:, 2].mean():+.2f}, {100 * g[:, 3].mean():.0f}% to compact-droplets-3")
z = decide(sorted(os.path.join(photos, f) for f in os.listdir(photos)))
print(f"photographs to compact-droplets-3: {sum(v > 0 for v in z.values())} of {len(z)}:",
      " ".join(sorted(n for n, v in z.items() if v <= 0)), "kept")
PY
fi

if want realismcontrol; then
  # RESULTS 4.38: the realism classifier with its control (the street alone) for every preset and
  # for glass-droplets' ranges, against the 44 photographs and the 16 beaded ones (clarity_*),
  # three seeds each; every set over the same 100 CamVid frames at 512x256, seed 11.
  link_cv100
  rc="$out/realism-control"
  rm -rf "$rc" && mkdir -p "$rc/clarity"
  for f in "$shared"/real-raindrop/clarity_*; do ln -s "$(realpath "$f")" "$rc/clarity/"; done
  glass_droplets_435 >"$rc/glass-droplets-4.35.json"
  glass_droplets_438 >"$rc/glass-droplets.json"
  small='s/"footprint_radius_cm": \[0.015, 0.12\]/"footprint_radius_cm": [0.01, 0.07]/; s/"contact_angle_deg": \[40, 90\]/"contact_angle_deg": [20, 50]/'
  edited_scene "$small; "'s/"f_number": \[1.6, 2.8\]/"f_number": [4, 8]/' "$rc/glass-droplets-4.35.json" 3 >"$rc/small-f4-8.json"
  edited_scene 's/"contact_angle_deg": \[20, 50\]/"contact_angle_deg": [40, 90]/' "$rc/glass-droplets.json" >"$rc/far-angles-40-90.json"
  edited_scene 's/"glass_distance_cm": \[12, 60\]/"glass_distance_cm": [10, 40]/; s/"footprint_radius_cm": \[0.025, 0.175\]/"footprint_radius_cm": [0.02, 0.15]/;
       s/"drop_count": \[400, 1000\]/"drop_count": [600, 1000]/' "$rc/glass-droplets.json" 3 >"$rc/glass-10-40.json"
  # Traced dark bands instead of black ones, with one and with 4 samples per pixel.
  trace='s/"dark_band": "black"/"dark_band": "trace"/'
  edited_scene "$trace" "$rc/glass-droplets.json" >"$rc/dark-band-trace.json"
  edited_scene "$trace; "'s/"samples_per_pixel": 1,/"samples_per_pixel": 4,/' "$rc/glass-droplets.json" 2 \
    >"$rc/dark-band-trace-4spp.json"
  sets=()
  for scene in paper real-photo lens-cover lens-cover-heavy lens-cover-merged windshield-day windshield-night \
               windshield-sharp "$rc/glass-droplets.json" "$rc/glass-droplets-4.35.json" "$rc/small-f4-8.json" \
               "$rc/far-angles-40-90.json" "$rc/glass-10-40.json" "$rc/dark-band-trace.json" \
               "$rc/dark-band-trace-4spp.json"; do
    name=$(basename "$scene" .json)
    build/raindrop-render -i "$out/cv100" -o "$rc/val-$name" --scene "$scene" --size 512x256 --seed 11 -q
    sets+=(--rendered "$rc/val-$name")
  done
  for photos in "$shared/real-raindrop" "$rc/clarity"; do
    for seed in 0 1 2; do
      $py -m raindrop_tools.realism --real-photos "$photos" "${sets[@]}" --limit 100 --seed "$seed" \
        --json "$rc/$(basename "$photos")-s$seed.json" >/dev/null
    done
  done
  # Looked at (not committed): centre crops of five beaded photographs at the working scale beside
  # glass-droplets with its 4.35 ranges and as it is now, doubled; photograph | 4.35 | now per row.
  beaded_sheet "$rc" val-glass-droplets-4.35 val-glass-droplets
  # The same sets against the real lens-cover pairs (their train split), with the drop statistics.
  $py -m raindrop_tools.realism --real-pairs "$shared/real-pairs" "${sets[@]}" --limit 100 --json "$rc/pairs.json" \
    >"$rc/pairs.md"
  realism_table "$rc" | tee "$rc/table.md"
fi

if want droplets2; then
  # RESULTS 4.39: compact-droplets-4, compact-droplets' mix with glass-droplets as 4.38 refitted it,
  # as the routed default's alternative, against the routed default on the validation sets (the
  # refitted preset's own val set too) and its masks on the 44 photographs.
  validation_sets
  d2="$out/droplets2"
  mkdir -p "$d2"
  glass_droplets_438 >"$d2/glass-droplets.json"
  [[ -f data/val-glass-droplets-now/manifest.jsonl ]] || build/raindrop-render -i "$out/cv100" \
    -o data/val-glass-droplets-now --scene "$d2/glass-droplets.json" --size 512x256 --seed 11 -q
  [[ -f data/train-glass-droplets-now/manifest.jsonl ]] || build/raindrop-render -i "$shared/camvid/train" \
    -o data/train-glass-droplets-now --scene "$d2/glass-droplets.json" --size 512x256 --variants 4 --seed 7 -q
  [[ -f data/train-windshield-sharp/manifest.jsonl ]] || build/raindrop-render -i "$shared/camvid/train" \
    -o data/train-windshield-sharp --scene windshield-sharp --size 512x256 --variants 4 --seed 7 -q
  [[ -f data/train-hi/manifest.jsonl ]] || render_train_hi
  sets=(real-pairs:train:0 val-glass-droplets-now:-:0 val-windshield-sharp:-:0 val-sparse:-:0)
  run=compact-droplets-4
  alternative_scored "$d2" "$run" "${sets[@]}"
  # Where the default's error on the refitted renders lies (masks against the renders' own), and
  # the default's own detector trained with them (compact-multiscale-droplets), without the router.
  SPLIT_ERROR=1 score_sets "$d2/split" routed "-j 2" real-pairs:train:0 val-glass-droplets-now:-:0 | tee "$d2/split.txt"
  SPLIT_ERROR=1 score_sets "$d2/split" "$run" "-j 2 --models out/models/cm-$run" real-pairs:train:0 \
    val-glass-droplets-now:-:0 | tee -a "$d2/split.txt"
  # Looked at (not committed): four refitted renders, the routed default's masks against theirs
  # (green: the render's mask, red: the detector's, yellow: both), its output.
  $py - "$d2/split/routed-val-glass-droplets-now--" "$d2/split-sheet.png" <<'PY'
import os, sys
import cv2
import numpy as np
d, out = sys.argv[1:]
rows = []
for n in sorted(os.listdir(f"{d}/set/rainy"))[::25][:4]:
    vis = np.zeros_like(cv2.imread(f"{d}/set/rainy/{n}"))
    vis[..., 1], vis[..., 2] = cv2.imread(f"{d}/set/mask/{n}", 0), cv2.imread(f"{d}/masks/{n}", 0)
    rows.append(np.hstack([cv2.imread(f"{d}/set/rainy/{n}"), vis, cv2.imread(f"{d}/out/{n}")]))
cv2.imwrite(out, np.vstack(rows))
PY
  main=compact-multiscale-droplets
  detector_run "$main"
  rm -rf "out/models/$main"
  $py -m raindrop_tools.export --run "tools/runs/$main" --reconstruction-from models/compact-multiscale \
    --name "$main" --out "out/models/$main"
  cp models/compact-multiscale/LARGE_DROPS "out/models/$main/"
  $py -m raindrop_tools.large_drop_growth "out/models/$main" 0.35
  {
    score_sets "$d2" default-no-router "-j 2 --no-router" "${sets[@]}"
    score_sets "$d2" "$main-no-router" "-j 2 --no-router --models out/models/$main" "${sets[@]}"
  } | tee "$d2/main-scores.txt"
  $py - "$d2" <<'PY' | tee "$d2/photo-masks.txt"
import os, sys
import cv2
d2 = sys.argv[1]
names = sorted(os.listdir(f"{d2}/photos-default/masks"))
for n in names:
    a, b = ((cv2.imread(f"{d2}/photos-{m}/masks/{n}", 0) > 0).mean() for m in ("default", "compact-droplets-4"))
    print(f"{n}: default {a:.3f}, compact-droplets-4 {b:.3f}")
PY
fi

if want infocus; then
  # RESULTS 4.40: drops in focus traced through the aperture. glass-droplets as it is (its drops in
  # focus traced through the aperture) and with "drops_in_focus": "centre" (through the lens' centre,
  # as before), over the same 100 CamVid frames as realismcontrol (512x256, seed 11), scored by the
  # realism classifier in one call per photo set and seed, crop for crop; a sheet (beaded photograph |
  # centre | aperture, not committed); the bench's accuracy/time table for the thin lens.
  link_cv100
  io="$out/infocus"
  rm -rf "$io" && mkdir -p "$io/clarity"
  for f in "$shared"/real-raindrop/clarity_*; do ln -s "$(realpath "$f")" "$io/clarity/"; done
  glass_droplets_438 >"$io/glass-droplets.json"  # the preset as 4.40 measured it
  edited_scene 's/"defocus": "layered",/"defocus": "layered", "drops_in_focus": "centre",/' "$io/glass-droplets.json" \
    >"$io/glass-droplets-centre.json"
  for scene in "$io/glass-droplets-centre.json" "$io/glass-droplets.json"; do
    build/raindrop-render -i "$out/cv100" -o "$io/val-$(basename "$scene" .json)" --scene "$scene" --size 512x256 \
      --seed 11 -q
  done
  # --paired: both sets cropped at the same places (the order of the sets in a call moved a set's
  # score by about 0.01 without it); six seeds.
  for photos in "$shared/real-raindrop" "$io/clarity"; do
    for seed in 0 1 2 3 4 5; do
      $py -m raindrop_tools.realism --real-photos "$photos" --rendered "$io/val-glass-droplets-centre" \
        --rendered "$io/val-glass-droplets" --limit 100 --seed "$seed" --paired \
        --json "$io/$(basename "$photos")-s$seed.json" >/dev/null
    done
  done
  realism_table "$io" | tee "$io/table.md"
  beaded_sheet "$io" val-glass-droplets-centre val-glass-droplets
  # (The bench renders the preset as it is now: its glass-droplets rows are 4.41's, not 4.40's.)
  build/raindrop-bench render --sections lens | tee "$io/lens-table.md"
fi

if want realismbar; then
  # RESULTS 4.41: issue 9's bar (each new preset closer to the photographs than `paper` and
  # `real-photo`) measured crop for crop: every preset rendered by this renderer over the same 100
  # CamVid frames (512x256, seed 11), scored by the realism classifier with --paired (every set
  # cropped at the same places), 6 seeds, against all 44 photographs and the 16 beaded ones; per
  # preset, the mean and the per-seed paired differences to paper and real-photo.
  link_cv100
  rb="$out/realism-bar"
  rm -rf "$rb" && mkdir -p "$rb/clarity"
  for f in "$shared"/real-raindrop/clarity_*; do ln -s "$(realpath "$f")" "$rb/clarity/"; done
  presets=(paper real-photo lens-cover lens-cover-heavy lens-cover-merged windshield-day windshield-night
           windshield-sharp glass-droplets)
  sets=()
  for p in "${presets[@]}"; do
    build/raindrop-render -i "$out/cv100" -o "$rb/val-$p" --scene "$p" --size 512x256 --seed 11 -q
    sets+=(--rendered "$rb/val-$p")
  done
  paired_realism "$rb" "$shared/real-raindrop" "$rb/clarity" -- "${sets[@]}" | tee "$rb/table.md"
  # The same sets against the real lens-cover pairs (train split), 3 seeds, paired.
  for seed in 0 1 2; do
    $py -m raindrop_tools.realism --real-pairs "$shared/real-pairs" --split train "${sets[@]}" --limit 100 \
      --seed "$seed" --paired --json "$rb/pairs-s$seed.json" >"$rb/pairs-s$seed.md"
  done
  $py - "$rb" <<'PY' | tee "$rb/pairs-table.md"
import json, sys
import numpy as np
rb = sys.argv[1]
acc = {}
for seed in range(3):
    for sc in json.load(open(f"{rb}/pairs-s{seed}.json"))["scores"]:
        name = sc["name"].split("(")[1].split(",")[0].removeprefix("val-")
        acc.setdefault(name, []).append((sc["classifier"]["accuracy"], sc["street"]["accuracy"], sc["drops_effect"]))
acc = {k: np.array(v) for k, v in acc.items()}
print("\nreal lens-cover pairs (train split), 3 seeds, paired\n\n"
      "| preset | accuracy | - paper | - real-photo | street alone | drops' effect |\n| --- | ---: | ---: | ---: | ---: | ---: |")
for name, v in acc.items():
    dp, dr = v[:, 0] - acc["paper"][:, 0], v[:, 0] - acc["real-photo"][:, 0]
    print(f"| {name} | {v[:, 0].mean():.3f} | {dp.mean():+.3f} ({dp.std(ddof=1):.3f}) | {dr.mean():+.3f} "
          f"({dr.std(ddof=1):.3f}) | {v[:, 1].mean():.3f} | {v[:, 2].mean():+.3f} |")
PY
fi

if want windshieldday; then
  # docs/RESULTS.md 4.42: compact-windshield's detector trained on with windshield-day drops (not
  # kept), each detector's recall and error split on windshield-day renders over the CamVid val
  # frames; then the default's 3RN and RFN fine-tuned with windshield drops (not kept). Both were
  # measured before compact-windshield had its own surround-fill area (4.44): 150 throughout.
  wd="$out/windshield-day"
  mkdir -p "$wd/models"
  validation_sets
  link_cv100
  [[ -f data/train-hi/manifest.jsonl ]] || render_train_hi
  for p in windshield-sharp windshield-day; do
    [[ -f data/train-$p/manifest.jsonl ]] || build/raindrop-render -i "$shared/camvid/train" -o "data/train-$p" \
      --scene "$p" --size 512x256 --variants 4 --seed 7 -q
  done
  [[ -f data/val-windshield-day/manifest.jsonl ]] || build/raindrop-render -i "$out/cv100" -o data/val-windshield-day \
    --scene windshield-day --size 512x256 --seed 11 -q
  [[ -f tools/runs/compact-windshield-day/checkpoints/stage1_step00000800.pt ]] ||
    $py -m raindrop_tools.train --config tools/configs/compact-windshield-day.yaml --out tools/runs/compact-windshield-day \
      --init-from models/compact-windshield --stage 1 --no-progress
  m="$wd/models/compact-windshield-day"
  $py -m raindrop_tools.export --run tools/runs/compact-windshield-day --reconstruction-from models/compact-multiscale \
    --name compact-windshield-day --out "$m"
  $py -m raindrop_tools.large_drop_growth "$m" 0.35
  cp models/compact-windshield/LARGE_DROPS "$m/"
  ln -sfn "$PWD/models/paper-real-coarse" "$wd/models/paper-real-coarse"
  val="real-pairs:train:0 val-sparse:-:0 val-windshield-sharp:-:0 val-size-512x288:-:0 val-size-1280x720:-:0"
  {
    split_sets "$wd" routed "-j 2 --surround-fill-area 150" val-windshield-day:-:0
    split_sets "$wd" ws-t0.75 "-j 2 --no-router --model-config compact-windshield --surround-fill-area 150" \
      val-windshield-day:-:0
    # shellcheck disable=SC2086
    score_sets "$wd" day "-j 2 --no-router --models $m" $val
    for t in 0.75 0.5 0.3; do
      split_sets "$wd" "day-t$t" "-j 2 --no-router --models $m --threshold $t" val-windshield-day:-:0
    done
  } | tee "$wd/detector.txt"
  # The alternative refitted on its outputs beside the default's: the fit's own gain.
  # shellcheck disable=SC2086
  score_sets "$wd" default "-j 2 --no-router --models models/compact-multiscale" $val >/dev/null
  fit=()
  for s in real-pairs-train val-sparse-- val-windshield-sharp-- val-size-512x288-- val-size-1280x720--; do
    fit+=(--set "$wd/default-$s/set" "$wd/default-$s/out" "$wd/day-$s/out")
  done
  $py -m raindrop_tools.detector_router fit --models models/compact-multiscale --alternative compact-windshield-day \
    "${fit[@]}" --out "$wd/ROUTER" | tee "$wd/fit.txt"
  # RESULTS 4.43: the default's 3RN and RFN fine-tuned with windshield drops (the detector, router
  # and large-drop models as shipped), routed, against the default on the validation sets; then
  # the new 3RN and RFN for the images the router sends to the windshield detector only (the
  # outputs picked per image by the router's choice).
  [[ -f tools/runs/compact-multiscale-windshield/checkpoints/stage2_step00000500.pt ]] ||
    $py -m raindrop_tools.train --config tools/configs/compact-multiscale-windshield.yaml \
      --out tools/runs/compact-multiscale-windshield --init-from models/compact-multiscale --no-progress
  $py -m raindrop_tools.export --run tools/runs/compact-multiscale-windshield --name compact-multiscale \
    --out "$wd/exported"
  c="$wd/models/compact-multiscale"
  rm -rf "$c" && mkdir -p "$c"
  cp models/compact-multiscale/{rdn.onnx,export.json,LARGE_DROPS,ROUTER} "$c/"
  cp "$wd"/exported/{rrn.onnx,rfn.onnx} "$c/"
  ln -sfn "$PWD/models/compact-windshield" "$wd/models/compact-windshield"
  sets="val-windshield-day:-:0 $val"
  {
    # shellcheck disable=SC2086
    score_sets "$wd" base "-j 2 --surround-fill-area 150" $sets
    # shellcheck disable=SC2086
    score_sets "$wd" cand "-j 2 --models $c --surround-fill-area 150" $sets
    for s in val-windshield-day-- real-pairs-train val-sparse-- val-windshield-sharp-- val-size-512x288-- val-size-1280x720--; do
      rm -rf "$wd/mix-$s" && mkdir -p "$wd/mix-$s/out"
      $py -m raindrop_tools.detector_router decide --models models/compact-multiscale --threads 2 "$wd/base-$s/set/rainy/"* |
        while read -r img _ who; do
          stem=$(basename "${img%.*}")
          for f in "$wd/base-$s/out/$stem".*; do
            pick="$wd/base-$s/out"
            [[ $who == main ]] || pick="$wd/cand-$s/out"
            ln -s "$PWD/$pick/$(basename "$f")" "$wd/mix-$s/out/"
          done
        done
      $py -m raindrop_tools.score_outputs --data "$wd/base-$s/set" --outputs "$wd/mix-$s/out" --label "routed images only $s"
    done
  } | tee "$wd/reconstruction.txt"
fi

if want fillarea; then
  # docs/RESULTS.md 4.44: compact-windshield's own surround-fill area (raindrop.surround_fill_area
  # 1500 in its rdn.onnx). The area chosen with its detector alone on the validation sets; the
  # routed default with it against the default before (--surround-fill-area 150 for both
  # detectors), on the validation sets and, once, on the test sets.
  fa="$out/fill-area"
  mkdir -p "$fa"
  validation_sets
  link_cv100
  size_sets val test-size
  [[ -f data/val-windshield-day/manifest.jsonl ]] || build/raindrop-render -i "$out/cv100" -o data/val-windshield-day \
    --scene windshield-day --size 512x256 --seed 11 -q
  for p in windshield-sharp windshield-day; do
    [[ -f data/test-$p/manifest.jsonl ]] || build/raindrop-render -i "$shared/camvid/test" -o "data/test-$p" \
      --scene "$p" --size 512x256 --seed 2 -q
  done
  val="val-windshield-day:-:0 real-pairs:train:0 val-sparse:-:0 val-windshield-sharp:-:0 val-size-512x288:-:0 val-size-1280x720:-:0"
  for a in 150 400 1500 3000; do
    # shellcheck disable=SC2086
    score_sets "$fa" "ws$a" "-j 2 --no-router --model-config compact-windshield --surround-fill-area $a" $val
  done | tee "$fa/validation.txt"
  {
    # shellcheck disable=SC2086
    score_sets "$fa" before "-j 2 --surround-fill-area 150" $val
    # shellcheck disable=SC2086
    score_sets "$fa" now "-j 2" $val
  } | tee "$fa/routed-validation.txt"
  {
    score_sets "$fa" before "-j 2 --surround-fill-area 150" real-pairs:test:0 test-windshield-day:-:0
    score_sets "$fa" now "-j 2" real-pairs:test:0 test-sparse:-:0 test-windshield-sharp:-:0 test-size-512x288:-:0 \
      test-size-1280x720:-:0 test-windshield-day:-:0
  } | tee "$fa/test.txt"
  build/raindrop-remove "$shared/real-raindrop" "$fa/photos-before" -q -j 2 --surround-fill-area 150
  build/raindrop-remove "$shared/real-raindrop" "$fa/photos-now" -q -j 2 --time 2>"$fa/photos-time.txt"
  photos_changed "$fa/photos-now" "$fa/photos-before" | tee "$fa/photos.txt"
fi

if want finedrops; then
  # docs/RESULTS.md 4.45: --fine-drops (the deciding detector at 1.5 times the working scale, small
  # parts over smooth surroundings filled). Windshield drops at 1280x720 over the 100 CamVid val
  # frames (seed 11) and the 233 test frames (seed 2), and the Cityscapes size sets; the default
  # with and without it; the 44 photographs; the time of three photographs, alternated.
  fd="$out/fine-drops"
  mkdir -p "$fd"
  link_cv100
  size_sets val test-size
  windshield_1280_sets
  # with_and_without SET...: the default's outputs without --fine-drops and with it, scored.
  with_and_without() {
    score_sets "$fd" base "-j 2" "$@"
    score_sets "$fd" fine "-j 2 --fine-drops" "$@"
  }
  with_and_without val-ws-1280x720:-:0 val-wsday-1280x720:-:0 val-size-1280x720:-:0 | tee "$fd/validation.txt"
  with_and_without test-ws-1280x720:-:0 test-wsday-1280x720:-:0 test-size-1280x720:-:0 | tee "$fd/test.txt"
  rm -rf "$fd/photos-base" "$fd/photos-fine"
  build/raindrop-remove "$shared/real-raindrop" "$fd/photos-base" -q -j 2
  build/raindrop-remove "$shared/real-raindrop" "$fd/photos-fine" -q -j 2 --fine-drops --time 2>"$fd/photos-time.txt"
  photos_changed "$fd/photos-fine" "$fd/photos-base" | tee "$fd/photos.txt"
  alternate_times 10 default windshield_2.jpg attgan-fork_test_5.png clarity_00309.png -- "" "--fine-drops" >"$fd/times.txt"
  median_times "$fd/times.txt" | tee "$fd/times-summary.txt"
fi

if want lanes; then
  # docs/RESULTS.md 1.2, "Camera rays in SIMD lanes" and "The thin lens's layer spread": the build
  # before both (754a2e2, built in a worktree under $ln/before) and this one side by side: the
  # same bytes for every preset and three more sizes, the render core by stage (three rounds),
  # end to end (two), the presets as programs on the 8 Cityscapes frames (two) and the lens
  # section (two). The register-width rows of 1.2 forced the width with a temporary variable
  # and are not repeated here.
  ln="$out/lanes"
  before="$ln/before"
  mkdir -p "$ln"
  built_at 754a2e2 "$before"
  city="$shared/cityscapes-mini"
  presets=(paper full-physics lens-cover lens-cover-heavy lens-cover-merged windshield-day windshield-night real-photo
           windshield-sharp glass-droplets)
  for args in "${presets[@]/#/--scene }" "--scene paper --size 512x256 -j1" \
              "--scene windshield-day --size 1024x512 --variants 3" "--scene lens-cover --size 640x320 --variants 2"; do
    for b in before now; do
      bin=$(bin_of "$b")
      rm -rf "$ln/render-$b"
      # shellcheck disable=SC2086
      "$bin/raindrop-render" --cityscapes "$city" --split all $args --seed 7 -q $([[ $args == *-j1* ]] || echo -j2) \
        --out "$ln/render-$b" >/dev/null
    done
    echo "$args: $(diff -r -x 'manifest*' "$ln/render-before" "$ln/render-now" | wc -l) lines differ"
  done | tee "$ln/same-bytes.txt"
  for r in 1 2 3; do
    for b in before now; do
      bin=$(bin_of "$b")
      echo "$b round $r"
      "$bin/raindrop-bench" render --sections core --frames 4 --repeats 5 2>/dev/null | grep -E '^\| [12] '
    done
  done | tee "$ln/core.txt"
  for r in 1 2; do
    for b in before now; do
      bin=$(bin_of "$b")
      echo "$b round $r"
      "$bin/raindrop-bench" render --sections time --repeats 3 2>/dev/null | grep -E '^\| (2048|512)'
      "$bin/raindrop-bench" render --sections lens --repeats 3 2>/dev/null | grep -E 'layered \(fast|aperture, 16'
    done
  done | tee "$ln/time-lens.txt"
  for p in "${presets[@]}"; do
    for r in 1 2; do
      for b in before now; do
        bin=$(bin_of "$b")
        rm -rf "$ln/run"
        s=$(date +%s%N)
        "$bin/raindrop-render" --cityscapes "$city" --split all --scene "$p" --seed 1 -q -j2 --out "$ln/run" >/dev/null
        echo "$p $b $(( ($(date +%s%N) - s) / 1000000 )) ms"
      done
    done
  done | tee "$ln/presets.txt"
  rm -rf "$ln/run" "$ln/render-before" "$ln/render-now"
fi

if want aperturelanes; then
  # docs/RESULTS.md 1.2, "The aperture reference in SIMD lanes, its rays culled": the build before
  # (70fba6c, in a worktree under $al/before) and this one side by side. The same bytes with the
  # 16-ray reference ("defocus": "aperture", the presets' files edited) wherever the reference's
  # arithmetic did not change (step 1 and 4 alone are the same bits; steps 2 and 3 move a few
  # values by one level: the differing values are counted), the layered presets whose drops in
  # focus take the lanes, and the camera section in turn (four rounds) and at 2048x1024 (one).
  al="$out/aperturelanes"
  before="$al/before"
  mkdir -p "$al"
  built_at 70fba6c "$before"
  city="$shared/cityscapes-mini"
  for p in lens-cover windshield-day windshield-night lens-cover-heavy real-photo glass-plate lens-cover-merged \
           glass-droplets; do
    edited_scene 's/"defocus": "[a-z-]*"/"defocus": "aperture", "aperture_samples": 16/' "scenes/$p.json" \
      >"$al/$p-aperture.json"
  done
  count_differences() {  # values that differ between two render folders, and the largest difference
    "$py" - "$1" "$2" <<'PY'
import sys, glob, os
import cv2, numpy as np
n = worst = total = 0
for f in sorted(glob.glob(os.path.join(sys.argv[1], "*", "*.png"))):
    a = cv2.imread(f, cv2.IMREAD_UNCHANGED).astype(int)
    b = cv2.imread(f.replace(sys.argv[1], sys.argv[2]), cv2.IMREAD_UNCHANGED).astype(int)
    d = np.abs(a - b)
    n += int((d > 0).sum()); worst = max(worst, int(d.max())); total += d.size
print(f"{n} of {total} values differ, by at most {worst}")
PY
  }
  for args in "--scene $al/lens-cover-aperture.json" "--scene $al/windshield-day-aperture.json" \
              "--scene $al/windshield-night-aperture.json" "--scene $al/lens-cover-heavy-aperture.json" \
              "--scene $al/real-photo-aperture.json" "--scene $al/glass-plate-aperture.json" \
              "--scene $al/lens-cover-merged-aperture.json" "--scene $al/glass-droplets-aperture.json" \
              "--scene glass-droplets" "--scene windshield-day" "--scene paper"; do
    for b in before now; do
      rm -rf "$al/render-$b"
      # shellcheck disable=SC2086
      "$(bin_of "$b")/raindrop-render" --cityscapes "$city" --split all $args --size 512x256 --seed 5 -q -j2 \
        --out "$al/render-$b" >/dev/null
    done
    echo "${args##*/}: $(count_differences "$al/render-before" "$al/render-now")"
  done | tee "$al/same-bytes.txt"
  for r in 1 2 3 4; do
    for b in before now; do
      echo "$b round $r"
      "$(bin_of "$b")/raindrop-bench" render --sections camera 2>/dev/null | grep -E '^\| (paper|lens-cover|windshield-day|glass)'
    done
  done | tee "$al/camera.txt"
  for b in before now; do
    echo "$b, 2048x1024"
    "$(bin_of "$b")/raindrop-bench" render --sections camera --lens-size 2048x1024 --frames 2 --repeats 2 2>/dev/null |
      grep -E '^\| (paper|lens-cover|windshield-day|glass)'
  done | tee "$al/camera-2048.txt"
  rm -rf "$al/render-before" "$al/render-now"
fi

if want glassplate; then
  # RESULTS 4.46: the glass-plate preset (dense, softly defocused drops on a plate 2-5 cm from the
  # lens) against the photographs by the realism classifier (crop for crop, 6 seeds: all 44 and the
  # 23 Qian-style 720x480 ones), and compact-plate (compact-windshield's detector trained with
  # glass-plate renders) as the routed default's alternative, on the validation sets, on the 44
  # photographs (mask coverage per photograph, a sheet), then the held-out test split.
  validation_sets
  gp="$out/glassplate"
  rm -rf "$gp" && mkdir -p "$gp/qian-style"
  for f in "$shared"/real-raindrop/{attgan,qian_demo,maxim,daclip}*; do ln -s "$(realpath "$f")" "$gp/qian-style/"; done
  [[ -f data/train/manifest.jsonl ]] || build/raindrop-render --input "$shared/camvid/train" --input "$shared/camvid/val" \
    --cityscapes "$shared/cityscapes-mini" --split train --size 512x256 --variants 6 --seed 1 --out data/train -q
  [[ -f data/train-hi/manifest.jsonl ]] || render_train_hi
  [[ -f data/train-windshield-sharp/manifest.jsonl ]] || build/raindrop-render -i "$shared/camvid/train" \
    -o data/train-windshield-sharp --scene windshield-sharp --size 512x256 --variants 4 --seed 7 -q
  [[ -f data/train-glass-plate/manifest.jsonl ]] || build/raindrop-render -i "$shared/camvid/train" \
    -o data/train-glass-plate --scene glass-plate --size 512x256 --variants 4 --seed 7 -q
  [[ -f data/val-glass-plate/manifest.jsonl ]] || build/raindrop-render -i "$out/cv100" -o data/val-glass-plate \
    --scene glass-plate --size 512x256 --seed 11 -q
  # Realism: the presets a Qian-style photograph could be confused with, over the same 100 frames.
  sets=()
  for p in paper real-photo lens-cover lens-cover-heavy windshield-day glass-plate; do
    build/raindrop-render -i "$out/cv100" -o "$gp/val-$p" --scene "$p" --size 512x256 --seed 11 -q
    sets+=(--rendered "$gp/val-$p")
  done
  paired_realism "$gp" "$shared/real-raindrop" "$gp/qian-style" -- "${sets[@]}" | tee "$gp/realism.md"
  # The detector: criteria in tools/configs/compact-plate.yaml, fixed before scoring.
  run=compact-plate
  alternative_scored "$gp" "$run" real-pairs:train:0 val-glass-plate:-:0 val-windshield-sharp:-:0 val-sparse:-:0
  # Where the error on glass-plate's renders lies: both detectors' masks against the renders' own.
  for m in routed "$run"; do
    flags="-j 2"
    [[ $m == routed ]] || flags="-j 2 --models out/models/cm-$m"
    split_sets "$gp/split" "$m" "$flags" val-glass-plate:-:0
  done | tee "$gp/split.txt"
  $py - "$gp" "$shared/real-raindrop" <<'PY' | tee "$gp/photo-masks.txt"
import os, sys
import cv2
import numpy as np
gp, photos = sys.argv[1:]
names = sorted(os.listdir(f"{gp}/photos-default/masks"))
cov = {n: [(cv2.imread(f"{gp}/photos-{m}/masks/{n}", 0) > 0).mean() for m in ("default", "compact-plate")] for n in names}
for n, (a, b) in cov.items():
    print(f"{n}: default {a:.3f}, compact-plate {b:.3f}")
qian = [n for n in names if n.startswith(("attgan", "qian_demo", "maxim", "daclip"))]
for label, group in (("all 44", names), ("23 Qian-style", qian)):
    a, b = np.array([cov[n] for n in group]).T
    print(f"{label}: mean mask {a.mean():.3f} -> {b.mean():.3f}; more of {(b > a + 0.005).sum()}, less of {(b < a - 0.005).sum()}")
# Looked at (not committed): Qian-style photographs, input | default (mask in red) | compact-plate.
def fit(im, w=360): return cv2.resize(im, (w, round(im.shape[0] * w / im.shape[1])), interpolation=cv2.INTER_AREA)
def shown(m, n):
    out = cv2.imread(f"{gp}/photos-{m}/out/" + next(f for f in os.listdir(f"{gp}/photos-{m}/out") if f.startswith(n[:-4] + ".")))
    mask = cv2.imread(f"{gp}/photos-{m}/masks/{n}", 0) > 0
    over = out.copy()
    over[mask] = (0.6 * over[mask] + [0, 0, 100]).astype(np.uint8)
    return np.hstack([fit(over), fit(out)])
rows = []
for n in qian[::3]:
    src = cv2.imread(os.path.join(photos, next(f for f in os.listdir(photos) if f.startswith(n[:-4] + "."))))
    rows.append(np.hstack([fit(src), shown("default", n), shown("compact-plate", n)]))
w = max(r.shape[1] for r in rows)
cv2.imwrite(f"{gp}/photos-sheet.png", np.vstack([cv2.copyMakeBorder(r, 0, 4, 0, w - r.shape[1], cv2.BORDER_CONSTANT) for r in rows]))
PY
fi

if want platerecon; then
  # RESULTS 4.47: compact-multiscale-plate, the default's 3RN and RFN fine-tuned with glass-plate
  # renders (criteria in its config, fixed before scoring), exported under the default's name beside
  # its detector, router and large-drop networks, against the routed default on the validation sets.
  validation_sets
  pr="$out/platerecon"
  mkdir -p "$pr"
  [[ -f data/train/manifest.jsonl ]] || build/raindrop-render --input "$shared/camvid/train" --input "$shared/camvid/val" \
    --cityscapes "$shared/cityscapes-mini" --split train --size 512x256 --variants 6 --seed 1 --out data/train -q
  [[ -f data/train-hi/manifest.jsonl ]] || render_train_hi
  [[ -f data/train-glass-plate/manifest.jsonl ]] || build/raindrop-render -i "$shared/camvid/train" \
    -o data/train-glass-plate --scene glass-plate --size 512x256 --variants 4 --seed 7 -q
  [[ -f data/val-glass-plate/manifest.jsonl ]] || build/raindrop-render -i "$out/cv100" -o data/val-glass-plate \
    --scene glass-plate --size 512x256 --seed 11 -q
  run=compact-multiscale-plate
  [[ -f "tools/runs/$run/checkpoints/stage2_step00000300.pt" ]] ||
    $py -m raindrop_tools.train --config "tools/configs/$run.yaml" --out "tools/runs/$run" --init-from models/compact-multiscale
  rm -rf "out/models/$run" && mkdir -p out/models
  $py -m raindrop_tools.export --run "tools/runs/$run" --name compact-multiscale --out "out/models/$run"
  $py -m raindrop_tools.large_drop_growth "out/models/$run" 0.35  # the default's (export.json)
  cp models/compact-multiscale/{ROUTER,LARGE_DROPS} "out/models/$run/"
  # The detector got no gradient (detection_weight 0, BatchNorm frozen): exported again, its graph
  # is serialized with other initializer names, and computes what the default's does.
  $py - "out/models/$run/rdn.onnx" models/compact-multiscale/rdn.onnx <<'PY'
import sys
import numpy as np
import onnxruntime as ort
x = np.random.default_rng(0).random((1, 3, 256, 512), dtype=np.float32)
new, shipped = (ort.InferenceSession(p, providers=["CPUExecutionProvider"]) for p in sys.argv[1:])
out = [s.run(None, {s.get_inputs()[0].name: x})[0] for s in (new, shipped)]
print(f"rdn.onnx against the default's on a random 512x256 input: max difference {np.abs(out[0] - out[1]).max():.3g}")
PY
  ln -sfn "$PWD/models/compact-windshield" out/models/compact-windshield
  ln -sfn "$PWD/models/paper-real-coarse" out/models/paper-real-coarse
  sets=(real-pairs:train:0 val-glass-plate:-:0 val-windshield-sharp:-:0 val-sparse:-:0)
  {
    score_sets "$pr" routed "-j 2" "${sets[@]}"
    score_sets "$pr" "$run" "-j 2 --models out/models/$run" "${sets[@]}"
  } | tee "$pr/scores.txt"
fi

# set_threshold FOLDER THRESHOLD: the detector threshold of a model folder, in each of its graphs
# and its export.json (detector_metadata.set_threshold).
set_threshold() {
  $py -c 'import sys; from raindrop_tools.detector_metadata import set_threshold; set_threshold(sys.argv[1], float(sys.argv[2]))' "$1" "$2"
}
# trained_head RUN STEPS CONFIG: trains the head of CONFIG into tools/runs/RUN unless its log
# reached STEPS (head.pt is also written every 500 steps on the way, so its presence says nothing).
trained_head() {
  grep -q "\"step\": $2," "tools/runs/$1/log.jsonl" 2>/dev/null ||
    $py -m raindrop_tools.train_head --config "$3" --out "tools/runs/$1"
}
# default_with_head HEAD DIR: the default's folder in DIR/models/compact-multiscale with the
# head HEAD (a train_head head.pt) in place of its own (shared_detector --replace), beside the
# other folders it names, at the committed head's threshold (shared_detector takes the
# teacher's pipeline, threshold 0.75; the committed head's since 4.50 is the one to compare at).
default_with_head() {
  local dir="$2/models"
  mkdir -p "$dir/compact-multiscale"
  cp models/compact-multiscale/* "$dir/compact-multiscale/"
  for m in compact-windshield paper-real-coarse; do ln -sfn "$PWD/models/$m" "$dir/$m"; done
  $py -m raindrop_tools.shared_detector --main "$dir/compact-multiscale" --replace \
    --head "$1" --like models/compact-windshield --out "$dir/compact-windshield-head"
  set_threshold "$dir/compact-windshield-head" \
    "$($py -c 'import json, sys; print(json.load(open(sys.argv[1]))["pipeline"]["threshold"])' models/compact-windshield-head/export.json)"
}
# lettering_damage DIR LABEL:FLAGS...: raindrop-remove FLAGS on the lettered drop-free frames
# (data/text-camvid-test, made unless there) into DIR/lettering-LABEL, and text_negatives damage's
# line for each.
lettering_damage() {
  local dir="$1" l
  shift
  [[ -d data/text-camvid-test ]] || $py -m raindrop_tools.text_negatives make --images "$shared/camvid/test" \
    --out data/text-camvid-test --count 100 --seed 3
  for l in "$@"; do
    rm -rf "$dir/lettering-${l%%:*}"
    # shellcheck disable=SC2086
    build/raindrop-remove data/text-camvid-test "$dir/lettering-${l%%:*}/out" --mask-dir "$dir/lettering-${l%%:*}/masks" \
      -q -j 2 ${l#*:}
    $py -m raindrop_tools.text_negatives damage --inputs data/text-camvid-test --outputs "$dir/lettering-${l%%:*}/out" \
      --masks "$dir/lettering-${l%%:*}/masks" --label "${l%%:*}"
  done
}
# router_sets: the held-out and validation sets a detector router is scored on (docs/RESULTS.md
# 4.48, 4.49), rendered unless there; their score_sets arguments in router_tests and router_vals.
router_sets() {
  validation_sets
  size_sets val test-size
  paper_sparse_scene
  [[ -f data/test-sparse/manifest.jsonl ]] || build/raindrop-render --input "$shared/camvid/test" \
    --cityscapes "$shared/cityscapes-mini" --split val --size 512x256 --variants 2 --seed 2 \
    --scene "$out/paper-sparse.json" --out data/test-sparse -q
  [[ -f data/test-windshield-sharp/manifest.jsonl ]] || build/raindrop-render -i "$shared/camvid/test" \
    -o data/test-windshield-sharp --scene windshield-sharp --size 512x256 --seed 2 -q
  router_tests=(real-pairs:test:0 test-sparse:-:0 test-windshield-sharp:-:0 test-size-512x288:-:0 test-size-1280x720:-:0)
  router_vals=(real-pairs:train:0 val-sparse:-:0 val-windshield-sharp:-:0)
}
# default_sets: the sets the default's changes are scored on since 4.57 (router_sets, the
# windshield sets at 1280x720 and val-glass-plate), each rendered once.
default_sets() {
  router_sets
  windshield_1280_sets
  link_cv100
  [[ -f data/val-glass-plate/manifest.jsonl ]] || build/raindrop-render -i "$out/cv100" -o data/val-glass-plate \
    --scene glass-plate --size 512x256 --seed 11 -q
}
# router_photos DIR NAME FLAGS...: the 44 photographs through raindrop-remove FLAGS into
# DIR/photos-NAME (outputs, masks, --time's lines) and its contact sheet DIR/photos-NAME-sheet.png.
router_photos() {
  local dir="$1" name="$2"
  shift 2
  rm -rf "$dir/photos-$name" && mkdir -p "$dir/photos-$name"
  build/raindrop-remove "$shared/real-raindrop" "$dir/photos-$name/removed" --mask-dir "$dir/photos-$name/masks" -q -j 2 \
    --time --contact-sheet "$dir/photos-$name-sheet.png" "$@" 2>"$dir/photos-$name/time.txt"
}

if want headrouter; then
  # RESULTS 4.48: compact-windshield's detector as a head on the default's own detector
  # (compact-windshield-head). Trained and written into the default's rdn.onnx unless the
  # committed graphs have it; then, side by side on the same sets: without the router, routed to
  # compact-windshield's own network (the default before: the same main graph, its ROUTER naming
  # that folder) and routed to the head (the default now); the head's map against its teacher's;
  # the 44 photographs; and the times of a routed and a kept photograph, alternated.
  router_sets
  hr="$out/headrouter"
  mkdir -p "$hr/models/full"
  if ! grep -q "^alternative compact-windshield-head$" models/compact-multiscale/ROUTER; then
    $py -m raindrop_tools.train_head --config tools/configs/compact-windshield-head.yaml --out tools/runs/compact-windshield-head
    $py -m raindrop_tools.shared_detector --main models/compact-multiscale --head tools/runs/compact-windshield-head/head.pt \
      --like models/compact-windshield --out models/compact-windshield-head
    sed -i 's/^alternative compact-windshield$/alternative compact-windshield-head/' models/compact-multiscale/ROUTER
  fi
  full="$hr/models/full"
  for f in rdn.onnx rrn.onnx rfn.onnx LARGE_DROPS; do ln -sfn "$PWD/models/compact-multiscale/$f" "$full/$f"; done
  for m in compact-windshield paper-real-coarse; do ln -sfn "$PWD/models/$m" "$hr/models/$m"; done
  sed 's/^alternative .*/alternative compact-windshield/' models/compact-multiscale/ROUTER >"$full/ROUTER"
  {
    score_sets "$hr" norouter "-j 2 --no-router" "${router_tests[@]}" "${router_vals[@]}"
    score_sets "$hr" full "-j 2 --models $full" "${router_tests[@]}" "${router_vals[@]}"
    score_sets "$hr" head "-j 2" "${router_tests[@]}" "${router_vals[@]}"
  } | tee "$hr/scores.txt"
  # The head's mask against its teacher's where both decide (threshold 0.75, before dilation), at
  # the working scale, on the validation sets and the photographs.
  $py - "$shared/real-raindrop" <<'PY' | tee "$hr/agreement.txt"
import glob, json, sys
import numpy as np, onnxruntime as ort
sys.path.insert(0, "tools")
from raindrop_tools import detector_router as DR
from raindrop_tools.imageio import read_rgb
so = ort.SessionOptions(); so.intra_op_num_threads = 2
main = ort.InferenceSession("models/compact-multiscale/rdn.onnx", so)
teacher = ort.InferenceSession("models/compact-windshield/rdn.onnx", so)
router = DR.read_router("models/compact-multiscale/ROUTER")
rp = json.load(open("data/real-pairs/realpairs.json"))["groups"]["train"]
sets = {"real pairs, train split": [f for f in sorted(glob.glob("data/real-pairs/rainy/*")) if any(f.split("/")[-1].startswith(g + "_") for g in rp)],
        "val-sparse": sorted(glob.glob("data/val-sparse/rainy/*")), "val-windshield-sharp": sorted(glob.glob("data/val-windshield-sharp/rainy/*")),
        "44 photographs": sorted(glob.glob(sys.argv[1] + "/*"))}
for name, files in sets.items():
    ious, routed = [], 0
    for f in files:
        x = DR.working_copy(read_rgb(f))
        h, w = x.shape[:2]
        t = np.pad(x.astype(np.float32) / 255, ((0, h % 2), (0, w % 2), (0, 0)), mode="edge").transpose(2, 0, 1)[None]
        p0, p1 = main.run(None, {"image": t})
        (pt,) = teacher.run(None, {"image": t})
        a, b = p1[0, 0, :h, :w] > 0.75, pt[0, 0, :h, :w] > 0.75
        ious.append((a & b).sum() / max(1, (a | b).sum()) if (a | b).any() else 1.0)
        routed += router.score(DR.features(p0[0, 0, :h, :w]))[0] > 0
    print(f"{name}: {len(files)} images, {routed} routed; mask IoU head vs compact-windshield at 0.75: mean {np.mean(ious):.3f}, median {np.median(ious):.3f}, min {np.min(ious):.3f}")
PY
  router_photos "$hr" head
  router_photos "$hr" full --models "$full"
  grep -c "detector 'compact-windshield-head'" "$hr/photos-head/time.txt" | sed 's/$/ of 44 photographs to the head/' | tee "$hr/photos.txt"
  photos_changed "$hr/photos-head/removed" "$hr/photos-full/removed" | tee -a "$hr/photos.txt"
  # Their final masks against each other, and eight photographs side by side (input | full
  # detector's mask | head's mask | full detector's output | head's output) in compare-head-full.png.
  $py - "$hr" "$shared/real-raindrop" <<'PY' | tee -a "$hr/photos.txt"
import glob, os, sys
import cv2, numpy as np
hr, photos = sys.argv[1:]
rs = []
for n in sorted(os.listdir(f"{hr}/photos-head/masks")):
    a, b = cv2.imread(f"{hr}/photos-full/masks/{n}", 0) > 0, cv2.imread(f"{hr}/photos-head/masks/{n}", 0) > 0
    rs.append((a.mean(), b.mean(), (a & b).sum() / max(1, (a | b).sum())))
f, h, iou = (np.array(c) for c in zip(*rs))
print(f"final masks: mean coverage full detector {f.mean():.3f}, head {h.mean():.3f}; head / full coverage median "
      f"{np.median(h / np.maximum(f, 1e-6)):.2f}; IoU mean {iou.mean():.2f}, median {np.median(iou):.2f}")
rows = []
for key in ("windshield_1", "windshield_2", "webcam_20181202", "qian_demo_case1", "clarity_00020", "maxim_0",
            "attgan_test_1", "clarity_00221"):
    stem = os.path.splitext(os.path.basename(glob.glob(f"{photos}/{key}*")[0]))[0]
    out = os.path.basename(glob.glob(f"{hr}/photos-head/removed/{stem}.*")[0])
    im = cv2.imread(glob.glob(f"{photos}/{stem}.*")[0])
    size = (int(im.shape[1] * 200 / im.shape[0]), 200)
    parts = [im, cv2.imread(f"{hr}/photos-full/masks/{stem}.png"), cv2.imread(f"{hr}/photos-head/masks/{stem}.png"),
             cv2.imread(f"{hr}/photos-full/removed/{out}"), cv2.imread(f"{hr}/photos-head/removed/{out}")]
    rows.append(np.hstack([cv2.resize(p, size, interpolation=cv2.INTER_AREA) for p in parts]))
w = max(r.shape[1] for r in rows)
cv2.imwrite(f"{hr}/compare-head-full.png", np.vstack([np.pad(r, ((0, 4), (0, w - r.shape[1]), (0, 0))) for r in rows]))
PY
  alternate_times 25 head windshield_2.jpg attgan-fork_test_5.png -- "" "--no-router" "--models $full" >"$hr/times.txt"
  median_times "$hr/times.txt" | tee "$hr/times-summary.txt"
fi

if want int8head; then
  # RESULTS 4.49: the int8 default (compact-multiscale-int8) with its router's alternative as a
  # head too: the merged fp32 graph quantized whole (quantize.py; its first map is the plain int8
  # graph's, bit for bit) and compact-windshield-head quantized into compact-windshield-head-int8
  # the same way. Side by side on the sets of 4.48: without the router, routed to
  # compact-windshield's own fp32 network (the int8 default before: the same main graph, its
  # ROUTER naming that folder) and routed to the int8 head (now); the 44 photographs; times.
  router_sets
  ih="$out/int8head"
  if ! grep -q "^alternative compact-windshield-head-int8$" models/compact-multiscale-int8/ROUTER; then
    $py -m raindrop_tools.quantize --models models/compact-multiscale --data data/train --out models/compact-multiscale-int8 --count 16
    $py -m raindrop_tools.quantize --models models/compact-windshield-head --data data/train \
      --out models/compact-windshield-head-int8 --count 16 --reuse-reconstruction models/compact-multiscale-int8
    echo paper-real-coarse-int8 >models/compact-windshield-head-int8/LARGE_DROPS
    sed -i 's/^alternative compact-windshield$/alternative compact-windshield-head-int8/' models/compact-multiscale-int8/ROUTER
  fi
  full="$ih/models/full"
  mkdir -p "$full"
  for f in rdn.onnx rrn.onnx rfn.onnx LARGE_DROPS; do ln -sfn "$PWD/models/compact-multiscale-int8/$f" "$full/$f"; done
  for m in compact-windshield paper-real-coarse-int8; do ln -sfn "$PWD/models/$m" "$ih/models/$m"; done
  sed 's/^alternative .*/alternative compact-windshield/' models/compact-multiscale-int8/ROUTER >"$full/ROUTER"
  int8="--models models/compact-multiscale-int8"
  {
    score_sets "$ih" norouter "-j 2 --no-router $int8" "${router_tests[@]}" "${router_vals[@]}"
    score_sets "$ih" full "-j 2 --models $full" "${router_tests[@]}" "${router_vals[@]}"
    score_sets "$ih" head "-j 2 $int8" "${router_tests[@]}" "${router_vals[@]}"
  } | tee "$ih/scores.txt"
  router_photos "$ih" head --models models/compact-multiscale-int8
  router_photos "$ih" full --models "$full"
  grep -c "detector 'compact-windshield-head-int8'" "$ih/photos-head/time.txt" | sed 's/$/ of 44 photographs to the head/' | tee "$ih/photos.txt"
  photos_changed "$ih/photos-head/removed" "$ih/photos-full/removed" | tee -a "$ih/photos.txt"
  # The int8 head's final masks against the fp32 head's (the default, 4.48) and the full detector's.
  $py - "$ih" "$out/headrouter" <<'PY' | tee -a "$ih/photos.txt"
import os, sys
import cv2, numpy as np
ih, hr = sys.argv[1:]
for name, other in (("int8 routed to compact-windshield", f"{ih}/photos-full/masks"), ("fp32 default (head)", f"{hr}/photos-head/masks")):
    if not os.path.isdir(other):
        continue
    rs = []
    for n in sorted(os.listdir(f"{ih}/photos-head/masks")):
        a, b = cv2.imread(f"{other}/{n}", 0) > 0, cv2.imread(f"{ih}/photos-head/masks/{n}", 0) > 0
        rs.append((a.mean(), b.mean(), (a & b).sum() / max(1, (a | b).sum())))
    f, h, iou = (np.array(c) for c in zip(*rs))
    print(f"int8 head's final masks vs {name}: mean coverage {h.mean():.3f} vs {f.mean():.3f}; IoU mean {iou.mean():.2f}, median {np.median(iou):.2f}")
PY
  alternate_times 15 int8-head windshield_2.jpg attgan-fork_test_5.png -- "$int8" "--no-router $int8" "--models $full" >"$ih/times.txt"
  median_times "$ih/times.txt" | tee "$ih/times-summary.txt"
fi

if want headthreshold; then
  # RESULTS 4.50: the threshold of the default's head (compact-windshield-head, 4.48), distilled
  # from a detector thresholded at 0.75: its map may be softer than its teacher's, and its masks
  # cover 92% of the teacher's on the photographs. Each threshold in turn as the head folder's
  # metadata (a copy; the graphs' nodes unchanged) on the validation sets. Rule fixed before
  # scoring: a threshold replaces 0.75 only if the mean of the three validation gains rises by at
  # least 0.05 dB and no set loses more than 0.1 dB (of several, the highest mean); then, and only
  # then, the test sets and the photographs.
  router_sets
  ht="$out/headthreshold"
  mkdir -p "$ht"
  {
    for thr in 0.75 0.7 0.65 0.6 0.5 0.4 0.3; do
      root="$ht/models/t$thr"
      mkdir -p "$root/main" "$root/compact-windshield-head"
      for f in rdn.onnx rrn.onnx rfn.onnx LARGE_DROPS ROUTER; do ln -sfn "$PWD/models/compact-multiscale/$f" "$root/main/$f"; done
      rm -f "$root/compact-windshield-head/"*
      cp models/compact-windshield-head/{rdn.onnx,rrn.onnx,rfn.onnx,LARGE_DROPS} "$root/compact-windshield-head/"
      ln -sfn "$PWD/models/paper-real-coarse" "$root/paper-real-coarse"
      set_threshold "$root/compact-windshield-head" "$thr"
      score_sets "$ht" "t$thr" "-j 2 --models $root/main" "${router_vals[@]}"
    done
  } | tee "$ht/scores.txt"
  # The rule above, over every threshold tried: of those that pass it, the highest mean.
  chosen=$(sweep_rule "$ht/scores.txt" t0.75)
  chosen=${chosen#t}
  echo "chosen threshold: $chosen" | tee -a "$ht/scores.txt"
  if [[ $chosen != 0.75 ]]; then
    score_sets "$ht" "test-t$chosen" "-j 2 --models $ht/models/t$chosen/main" "${router_tests[@]}" | tee "$ht/scores-test.txt"
    router_photos "$ht" "t$chosen" --models "$ht/models/t$chosen/main"
  fi
  # Adopted (4.50) as the metadata of compact-windshield-head's three graphs and export.json, and
  # so of its int8 copy (quantize --reuse-reconstruction, as in int8head); then the int8 default,
  # routed, on the test sets.
  if [[ $chosen != 0.75 ]] && ! $py -c 'import onnx, sys; m = onnx.load(sys.argv[1]); sys.exit(0 if {p.key: p.value for p in m.metadata_props}["raindrop.threshold"] == sys.argv[2] else 1)' \
      models/compact-windshield-head/rdn.onnx "$chosen"; then
    set_threshold models/compact-windshield-head "$chosen"
    $py -m raindrop_tools.quantize --models models/compact-windshield-head --data data/train \
      --out models/compact-windshield-head-int8 --count 16 --reuse-reconstruction models/compact-multiscale-int8
  fi
  score_sets "$ht" int8 "-j 2 --models models/compact-multiscale-int8" "${router_tests[@]}" | tee "$ht/scores-int8.txt"
  # What the lower threshold costs in time: the default (now), its 0.75 copy and --no-router, alternated.
  alternate_times 25 "t$chosen" windshield_2.jpg attgan-fork_test_7.png -- "" "--models $ht/models/t0.75/main" "--no-router" \
    >"$ht/times.txt"
  median_times "$ht/times.txt" | tee "$ht/times-summary.txt"
fi

# default_copies ROOT MAIN_K HEAD_K: the default (ROOT/main) and its head
# (ROOT/compact-windshield-head) as copies whose graphs carry the mask dilations MAIN_K and HEAD_K
# (detector_metadata.set_dilation; the graphs' nodes unchanged), the large-drop models linked: a
# sweep changes other metadata of the copies.
default_copies() {
  local root="$1" f
  mkdir -p "$root/main" "$root/compact-windshield-head"
  rm -f "$root/main/"* "$root/compact-windshield-head/"*
  cp models/compact-multiscale/{rdn.onnx,rrn.onnx,rfn.onnx,LARGE_DROPS,ROUTER,export.json} "$root/main/"
  cp models/compact-windshield-head/{rdn.onnx,rrn.onnx,rfn.onnx,LARGE_DROPS,export.json} "$root/compact-windshield-head/"
  ln -sfn "$PWD/models/paper-real-coarse" "$root/paper-real-coarse"
  for f in main:$2 compact-windshield-head:$3; do
    $py -c 'import sys; from raindrop_tools.detector_metadata import set_dilation; set_dilation(sys.argv[1], int(sys.argv[2]))' \
      "$root/${f%%:*}" "${f##*:}"
  done
}

# dilation_extra: the part of the dilation section beside its rule (RESULTS 4.51).
dilation_extra() {
  local dl="$out/dilation" l
  # --dilation 7 (both detectors) on the validation sets, for the README's figures.
  default_copies "$dl/models/k7-7" 7 7
  score_sets "$dl" "k7-7" "-j 2 --models $dl/models/k7-7/main" "${router_vals[@]}" | tee "$dl/scores-k7-7.txt"
  for l in k3-3 k3-7 k3-9; do score_sets "$dl" "gp-$l" "-j 2 --models $dl/models/$l/main" val-glass-plate:-:0; done \
    | tee "$dl/scores-glass-plate.txt"
  # The held-out real pairs once with --dilation 7, after the rule had decided (nothing is chosen on them).
  for l in default:"" dilation7:"--dilation 7"; do
    score_sets "$dl" "test-${l%%:*}" "-j 2 ${l#*:}" real-pairs:test:0
  done | tee "$dl/scores-test-dilation7.txt"
  router_photos "$dl" default
  router_photos "$dl" dilation7 --dilation 7
  photos_changed "$dl/photos-dilation7/removed" "$dl/photos-default/removed" | tee "$dl/photos-changed-dilation7.txt"
}

if want dilation; then
  # RESULTS 4.51: the mask dilation k of the default's two detectors, 3 since the first models. The
  # photographs' outputs keep the rims and halos of drops whose cores the masks cover. The head's
  # (which decides 42 of the 44 photographs) first, with the main detector's at 3; then the main
  # detector's, with the head's chosen. Each on the validation sets, the rule of sweep_rule fixed
  # before scoring; the test sets and the photographs only for a k that the rule chooses.
  router_sets
  dl="$out/dilation"
  mkdir -p "$dl"
  {
    for hk in 3 5 7 9; do
      default_copies "$dl/models/k3-$hk" 3 "$hk"
      score_sets "$dl" "k3-$hk" "-j 2 --models $dl/models/k3-$hk/main" "${router_vals[@]}"
    done
  } | tee "$dl/scores-head.txt"
  head_label=$(sweep_rule "$dl/scores-head.txt" k3-3)
  hk=${head_label#k3-}
  echo "chosen head dilation: $hk" | tee -a "$dl/scores-head.txt"
  {
    grep "^k3-$hk " "$dl/scores-head.txt"
    for mk in 5 7; do
      default_copies "$dl/models/k$mk-$hk" "$mk" "$hk"
      score_sets "$dl" "k$mk-$hk" "-j 2 --models $dl/models/k$mk-$hk/main" "${router_vals[@]}"
    done
  } | tee "$dl/scores-main.txt"
  chosen=$(sweep_rule "$dl/scores-main.txt" "k3-$hk")
  echo "chosen: $chosen (main-head)" | tee -a "$dl/scores-main.txt"
  if [[ $chosen != k3-3 ]]; then
    for label in k3-3 "$chosen"; do
      score_sets "$dl" "test-$label" "-j 2 --models $dl/models/$label/main" "${router_tests[@]}"
      router_photos "$dl" "$label" --models "$dl/models/$label/main"
    done | tee "$dl/scores-test.txt"
    photos_changed "$dl/photos-$chosen/removed" "$dl/photos-k3-3/removed" | tee "$dl/photos-changed.txt"
  fi
  # Beside the rule: the Qian-style glass-plate renders (the photographs' dense soft drops, 4.46),
  # and the 44 photographs with --dilation 7 (both detectors) against the default, looked at.
  dilation_extra
fi

if want coarsescales; then
  # RESULTS 4.52: the large-drop networks (paper-real-coarse) trained with the real pairs' train
  # split at three scales instead of one (tools/configs/paper-real-coarse-scales.yaml), beside a
  # control: paper-real-coarse's own recipe retrained the same day on the same renders (the
  # thin-lens training renders data/train-mix are re-rendered by photoreal's commands when absent).
  # Rule in the config: the train split and the validation sets within 0.05 dB of the committed
  # model's, then the held-out test split once.
  router_sets
  for scene in lens-cover windshield-day; do
    [[ -f data/train-$scene/manifest.jsonl ]] || build/raindrop-render -i "$shared/camvid/train" -o "data/train-$scene" \
      --scene "$scene" --size 512x256 --variants 4 --seed 7 -q
  done
  [[ -f data/train-cs-lens/manifest.jsonl ]] || build/raindrop-render --cityscapes "$shared/cityscapes-mini" --split train \
    -o data/train-cs-lens --scene lens-cover --size 512x256 --variants 20 --seed 8 -q
  [[ -f data/train-mix/manifest.jsonl ]] || $py -m raindrop_tools.merge_datasets --out data/train-mix data/train-lens-cover \
    data/train-windshield-day data/train-cs-lens
  real_pairs_data
  cs="$out/coarsescales"
  mkdir -p "$cs"
  for run in paper-real-coarse-scales:paper-real-coarse-scales paper-real-coarse-control:paper-real-coarse; do
    name=${run%%:*} config=${run##*:}
    if [[ ! -f out/models/$name/rrn.onnx ]]; then
      timed "train $name" nice -n 10 $py -m raindrop_tools.train --config "tools/configs/$config.yaml" \
        --out "tools/runs/$name" --init-from models/paper
      $py -m raindrop_tools.export --run "tools/runs/$name" --out "out/models/$name"
    fi
  done
  {
    score_sets "$cs" now "-j 2" "${router_vals[@]}"
    score_sets "$cs" scales "-j 2 --large-drop-models out/models/paper-real-coarse-scales" "${router_vals[@]}"
    score_sets "$cs" control "-j 2 --large-drop-models out/models/paper-real-coarse-control" "${router_vals[@]}"
  } | tee "$cs/scores-val.txt"
fi

if want mainthreshold; then
  # RESULTS 4.51, last paragraph: the main detector's threshold (0.3 since the first models),
  # swept as 4.50 swept the head's, with the same rule.
  router_sets
  mt="$out/mainthreshold"
  mkdir -p "$mt"
  for thr in 0.3 0.2 0.25 0.35 0.4; do
    root="$mt/models/t$thr"
    default_copies "$root" 3 3
    set_threshold "$root/main" "$thr"
    score_sets "$mt" "t$thr" "-j 2 --models $root/main" "${router_vals[@]}"
  done | tee "$mt/scores.txt"
  echo "chosen threshold: $(sweep_rule "$mt/scores.txt" t0.3)" | tee -a "$mt/scores.txt"
fi

if want rim; then
  # RESULTS 4.54: the parts the surround fills grown into their rims first (--surround-fill-rim,
  # 3 by default since). The validation sets (router_vals, windshield drops at 1280x720 over the
  # 100 CamVid val frames, the Cityscapes 1280x720 frames, glass-plate) for reaches 0, 2, 3 and 5;
  # the 44 photographs with 0 and 3; the times of two photographs, alternated; the test sets once.
  # (Run with today's build these are the mended figures of 4.54's last paragraphs.)
  router_sets
  rm_="$out/rim"
  mkdir -p "$rm_"
  windshield_1280_sets
  [[ -f data/val-glass-plate/manifest.jsonl ]] || build/raindrop-render -i "$out/cv100" -o data/val-glass-plate \
    --scene glass-plate --size 512x256 --seed 11 -q
  for r in 0 2 3 5; do
    score_sets "$rm_" "rim$r" "-j 2 --surround-fill-rim $r" "${router_vals[@]}" val-ws-1280x720:-:0 \
      val-wsday-1280x720:-:0 val-size-1280x720:-:0 val-glass-plate:-:0
  done | tee "$rm_/scores.txt"
  router_photos "$rm_" rim0 --surround-fill-rim 0
  router_photos "$rm_" rim3 --surround-fill-rim 3
  photos_changed "$rm_/photos-rim3/removed" "$rm_/photos-rim0/removed" | tee "$rm_/photos-changed-rim3.txt"
  alternate_times 10 default windshield_2.jpg clarity_00309.png -- "--surround-fill-rim 0" "--surround-fill-rim 3" \
    >"$rm_/times.txt"
  median_times "$rm_/times.txt" | tee "$rm_/times-summary.txt"
  for l in rim0:"--surround-fill-rim 0" rim3:""; do
    score_sets "$rm_" "test-${l%%:*}" "-j 2 ${l#*:}" "${router_tests[@]}" test-ws-1280x720:-:0 test-wsday-1280x720:-:0
  done | tee "$rm_/test.txt"
fi

if want headtext; then
  # RESULTS 4.56: the default's windshield head fine-tuned with lettering as negatives
  # (tools/configs/compact-windshield-head-text.yaml). The rule, fixed before scoring: it
  # replaces the committed head only if, on 100 drop-free CamVid test frames with lettering drawn
  # on (data/text-camvid-test: backgrounds no network trained on), the output's PSNR-Y against
  # the input rises by at least 2 dB and fewer pixels are marked; on the validation sets of 4.54
  # no set loses more than 0.1 dB and the mean gain falls by at most 0.02 dB; and on the 44
  # photographs nothing is newly damaged (by eye, against the default's outputs).
  router_sets
  windshield_1280_sets
  [[ -f data/val-glass-plate/manifest.jsonl ]] || build/raindrop-render -i "$out/cv100" -o data/val-glass-plate \
    --scene glass-plate --size 512x256 --seed 11 -q
  ht="$out/headtext"
  trained_head compact-windshield-head 3000 tools/configs/compact-windshield-head.yaml
  trained_head compact-windshield-head-text 1000 tools/configs/compact-windshield-head-text.yaml
  default_with_head tools/runs/compact-windshield-head-text/head.pt "$ht"
  # The baseline: the same frames without lettering, through the default.
  $py -m raindrop_tools.text_negatives make --images "$shared/camvid/test" --out "$ht/plain" --count 100 --no-lettering
  rm -rf "$ht/plain-default"
  build/raindrop-remove "$ht/plain" "$ht/plain-default/out" --mask-dir "$ht/plain-default/masks" -q -j 2
  $py -m raindrop_tools.text_negatives damage --inputs "$ht/plain" --outputs "$ht/plain-default/out" \
    --masks "$ht/plain-default/masks" --label "default, the frames without lettering" | tee "$ht/plain.txt"
  lettering_damage "$ht" default:"" text:"--models $ht/models/compact-multiscale" | tee "$ht/lettering.txt"
  score_sets "$ht" text "-j 2 --models $ht/models/compact-multiscale" "${router_vals[@]}" val-ws-1280x720:-:0 \
    val-wsday-1280x720:-:0 val-size-1280x720:-:0 val-glass-plate:-:0 | tee "$ht/scores.txt"
  score_sets "$ht" default "-j 2" "${router_vals[@]}" val-ws-1280x720:-:0 val-wsday-1280x720:-:0 \
    val-size-1280x720:-:0 val-glass-plate:-:0 | tee -a "$ht/scores.txt"
  router_photos "$ht" default
  router_photos "$ht" text --models "$ht/models/compact-multiscale"
  photos_changed "$ht/photos-text/removed" "$ht/photos-default/removed" | tee "$ht/photos-changed.txt"
fi
if want headnight; then
  # RESULTS 4.57: the default's windshield head fine-tuned with night drops, taught by the
  # renderer's masks where the teacher never saw such drops
  # (tools/configs/compact-windshield-head-night.yaml, which states the rule fixed before scoring).
  default_sets
  [[ -f data/val-wsnight-1280x720/manifest.jsonl ]] || build/raindrop-render -i "$out/cv100" \
    -o data/val-wsnight-1280x720 --scene windshield-night --size 1280x720 --seed 11 -q
  [[ -f data/train-windshield-night/manifest.jsonl ]] || build/raindrop-render -i "$shared/camvid/train" \
    -o data/train-windshield-night --scene windshield-night --size 512x256 --variants 4 --seed 7 -q
  hn="$out/headnight"
  trained_head compact-windshield-head 3000 tools/configs/compact-windshield-head.yaml
  trained_head compact-windshield-head-night 1000 tools/configs/compact-windshield-head-night.yaml
  default_with_head tools/runs/compact-windshield-head-night/head.pt "$hn"
  for l in default:"-j 2" night:"-j 2 --models $hn/models/compact-multiscale"; do
    split_sets "$hn" "${l%%:*}" "${l#*:}" val-wsnight-1280x720:-:0
    score_sets "$hn" "${l%%:*}" "${l#*:}" "${router_vals[@]}" val-ws-1280x720:-:0 val-wsday-1280x720:-:0 \
      val-size-1280x720:-:0 val-glass-plate:-:0
  done | tee "$hn/scores.txt"
  lettering_damage "$hn" default:"" night:"--models $hn/models/compact-multiscale" | tee "$hn/lettering.txt"
  router_photos "$hn" default
  router_photos "$hn" night --models "$hn/models/compact-multiscale"
  photos_changed "$hn/photos-night/removed" "$hn/photos-default/removed" | tee "$hn/photos-changed.txt"
fi
if want headdiscs; then
  # RESULTS 4.73: the default's windshield head fine-tuned with lens-cover discs (small drops far
  # out of focus), taught by the renderer's masks, started from the committed head read back from
  # the default's folder (tools/configs/compact-windshield-head-discs.yaml, which states the rule
  # fixed before scoring).
  default_sets
  [[ -f data/train-hi/manifest.jsonl ]] || render_train_hi
  [[ -f data/train-windshield-sharp/manifest.jsonl ]] || build/raindrop-render -i "$shared/camvid/train" \
    -o data/train-windshield-sharp --scene windshield-sharp --size 512x256 --variants 4 --seed 7 -q
  [[ -f data/train-lens-discs/manifest.jsonl ]] || build/raindrop-render -i "$shared/camvid/train" \
    -o data/train-lens-discs --scene tools/configs/lens-cover-discs.json --size 512x256 --variants 4 --seed 7 -q
  [[ -f data/val-lens-discs-720x480/manifest.jsonl ]] || build/raindrop-render -i "$out/cv100" \
    -o data/val-lens-discs-720x480 --scene tools/configs/lens-cover-discs.json --size 720x480 --seed 11 -q
  hd="$out/headdiscs"
  trained_head compact-windshield-head-discs 1000 tools/configs/compact-windshield-head-discs.yaml
  default_with_head tools/runs/compact-windshield-head-discs/head.pt "$hd"
  # Both float (the committed head is the float default's; on a CPU with VNNI the default would
  # otherwise be the int8 copy, 4.60).
  for l in default:"-j 2 --models models/compact-multiscale" discs:"-j 2 --models $hd/models/compact-multiscale"; do
    split_sets "$hd" "${l%%:*}" "${l#*:}" val-lens-discs-720x480:-:0
    score_sets "$hd" "${l%%:*}" "${l#*:}" "${router_vals[@]}" val-ws-1280x720:-:0 val-wsday-1280x720:-:0 \
      val-size-1280x720:-:0 val-glass-plate:-:0
  done | tee "$hd/scores.txt"
  lettering_damage "$hd" default:"--models models/compact-multiscale" discs:"--models $hd/models/compact-multiscale" |
    tee "$hd/lettering.txt"
  router_photos "$hd" default --models models/compact-multiscale
  router_photos "$hd" discs --models "$hd/models/compact-multiscale"
  photos_changed "$hd/photos-discs/removed" "$hd/photos-default/removed" | tee "$hd/photos-changed.txt"
fi
if want workers; then
  # RESULTS 4.59: folder mode with two images at once (--workers 2, each on one of the two
  # threads) against one at a time on both, rounds alternated: wall time, peak memory, and the
  # outputs compared byte for byte.
  windshield_1280_sets
  real_pairs_data
  wk="$out/workers"
  mkdir -p "$wk"
  link_set data/real-pairs "$wk/pairs" test 0
  link_set data/val-wsday-1280x720 "$wk/wsday" - 0
  : >"$wk/times.txt"
  for folder in "$shared/real-raindrop" "$wk/pairs/rainy" "$wk/wsday/rainy"; do
    for round in 1 2 3 4; do
      order=(1 2)
      ((round % 2)) || order=(2 1)
      for w in "${order[@]}"; do
        rm -rf "$wk/out-$w"
        s=$(date +%s%N)
        /usr/bin/time -f "%M" -o "$wk/rss" build/raindrop-remove "$folder" "$wk/out-$w" -j 2 -q --workers "$w"
        echo "$(basename "$(dirname "$folder")")/$(basename "$folder") workers-$w $(( ($(date +%s%N) - s) / 1000000 )) ms, peak RSS $(( $(cat "$wk/rss") / 1024 )) MB" |
          tee -a "$wk/times.txt"
      done
    done
    diff -r "$wk/out-1" "$wk/out-2" >/dev/null && echo "$folder: the same bytes" | tee -a "$wk/times.txt"
  done
fi

if want int8default; then
  # RESULTS 4.60: models/DEFAULT's int8 copy on CPUs with VNNI, its RFN kept in float. The float
  # default, the int8 copy as it was (every network int8; from git, 1ad2fb0) and as it is, named
  # explicitly (so that the figures do not depend on the CPU that runs this), side by side: the
  # validation sets, then the test sets once; the 44 photographs; process start to file written
  # on two photographs, rounds alternated, with this machine's choice ("") beside.
  default_sets
  i8="$out/int8default"
  mkdir -p "$i8"
  if ! grep -q '"kept_float"' models/compact-multiscale-int8/export.json; then
    [[ -f data/train/manifest.jsonl ]] || build/raindrop-render --input "$shared/camvid/train" --input "$shared/camvid/val" \
      --cityscapes "$shared/cityscapes-mini" --split train --size 512x256 --variants 6 --seed 1 --out data/train -q
    $py -m raindrop_tools.quantize --models models/compact-multiscale --data data/train --out models/compact-multiscale-int8 \
      --count 16 --keep-float rfn
    $py -m raindrop_tools.quantize --models models/compact-windshield-head --data data/train \
      --out models/compact-windshield-head-int8 --count 16 --reuse-reconstruction models/compact-multiscale-int8
  fi
  allint8="$i8/models"
  rm -rf "$allint8" && mkdir -p "$allint8"
  git archive 1ad2fb0 models/compact-multiscale-int8 models/compact-windshield-head-int8 | tar -x -C "$allint8" --strip-components=1
  ln -sfn "$PWD/models/paper-real-coarse-int8" "$allint8/paper-real-coarse-int8"
  vals=(real-pairs:train:0 val-sparse:-:0 val-windshield-sharp:-:0 val-ws-1280x720:-:0 val-wsday-1280x720:-:0
        val-size-1280x720:-:0 val-glass-plate:-:0)
  tests=(real-pairs:test:0 test-sparse:-:0 test-windshield-sharp:-:0 test-size-512x288:-:0 test-size-1280x720:-:0
         test-ws-1280x720:-:0 test-wsday-1280x720:-:0)
  variants=("compact-multiscale|--model-config compact-multiscale" "all-int8|--models $allint8/compact-multiscale-int8"
            "compact-multiscale-int8|--model-config compact-multiscale-int8")
  for v in "${variants[@]}"; do score_sets "$i8" "${v%%|*}" "-j 2 ${v#*|}" "${vals[@]}"; done | tee "$i8/scores-val.txt"
  for v in "${variants[@]}"; do score_sets "$i8" "${v%%|*}" "-j 2 ${v#*|}" "${tests[@]}"; done | tee "$i8/scores-test.txt"
  for m in compact-multiscale compact-multiscale-int8; do router_photos "$i8" "$m" --model-config "$m"; done
  photos_changed "$i8/photos-compact-multiscale/removed" "$i8/photos-compact-multiscale-int8/removed" | tee "$i8/photos.txt"
  alternate_times 15 default windshield_2.jpg attgan-fork_test_5.png -- "" "--model-config compact-multiscale" \
    "--model-config compact-multiscale-int8" >"$i8/times.txt"
  median_times "$i8/times.txt" | tee "$i8/times-summary.txt"
fi

if want sampledlayers; then
  # RESULTS 4.63: the thin lens's layers with circles of 48-96 px spread at every second or third
  # pixel and row and interpolated between; the antialiased disk's rim areas by chord and octant;
  # one comparison per sRGB code. The build before (a340440, in a worktree under $sl/before) and
  # this one: what changes in the renders (windshield-day at f/2 with the glass at 10 cm at
  # 2048x1024, the issue's camera; the presets at 1024x512), the camera section at 2048x1024 and
  # that windshield end to end, rounds alternated. Run after 7a0975a, "now" also has the frame's
  # copies on all threads (4.63's last paragraphs: the same bytes, a few ms less per frame).
  sl="$out/sampledlayers"
  before="$sl/before"
  mkdir -p "$sl"
  built_at a340440 "$before"
  city="$shared/cityscapes-mini"
  edited_scene 's/"glass_distance_cm": \[5, 30\]/"glass_distance_cm": [10, 10]/; s/"f_number": \[1.8, 5.6\]/"f_number": [2, 2]/' \
    scenes/windshield-day.json 2 >"$sl/windshield-f2.json"
  compare_renders() {  # values that differ between two render folders; rainy and alpha inside the coverage
    "$py" - "$1" "$2" <<'PY'
import sys, glob, os
import cv2, numpy as np
a_dir, b_dir = sys.argv[1], sys.argv[2]
files = differ = 0
worst = {"rainy": 0.0, "alpha": 0.0}
sq = {"rainy": 0.0, "alpha": 0.0}
n = 0
mask_changed = mask_px = 0
for f in sorted(glob.glob(os.path.join(a_dir, "rainy", "*.png"))):
    name = os.path.basename(f)
    for kind in ("rainy", "alpha", "mask"):
        pa, pb = os.path.join(a_dir, kind, name), os.path.join(b_dir, kind, name)
        if not os.path.exists(pa):
            continue
        files += 1
        differ += open(pa, "rb").read() != open(pb, "rb").read()
    rainy_a = cv2.imread(f).astype(float)
    if not os.path.exists(os.path.join(a_dir, "alpha", name)):  # no thin lens: no coverage, the whole frame
        alpha_a = alpha_b = np.zeros(rainy_a.shape[:2])
        inside = np.ones(rainy_a.shape[:2], bool)
    else:
        alpha_a = cv2.imread(os.path.join(a_dir, "alpha", name), cv2.IMREAD_UNCHANGED).astype(float) / 65535 * 255
        alpha_b = cv2.imread(os.path.join(b_dir, "alpha", name), cv2.IMREAD_UNCHANGED).astype(float) / 65535 * 255
        inside = alpha_a > 0
    n += int(inside.sum())
    for kind, a, b in (("rainy", rainy_a, cv2.imread(os.path.join(b_dir, "rainy", name)).astype(float)),
                       ("alpha", alpha_a, alpha_b)):
        d = np.abs(a - b)
        worst[kind] = max(worst[kind], float(d.max()))
        sq[kind] += float((d[inside] ** 2).sum()) / (3 if kind == "rainy" else 1)
    ma = cv2.imread(os.path.join(a_dir, "mask", name), 0)
    mb = cv2.imread(os.path.join(b_dir, "mask", name), 0)
    mask_changed += int((ma != mb).sum())
    mask_px += int((ma > 0).sum())
rms = {k: (sq[k] / max(n, 1)) ** 0.5 for k in sq}
print(f"{differ} of {files} files differ; rainy worst {worst['rainy']:.0f} levels, RMS {rms['rainy']:.3f} inside the coverage; "
      f"coverage worst {worst['alpha']:.2f}/255, RMS {rms['alpha']:.3f}/255; mask {mask_changed} of {mask_px} pixels changed")
PY
  }
  # SCENE|SIZE (native: the frames' 2048x1024)
  for run in "$sl/windshield-f2.json|native" "$sl/windshield-f2.json|1024x512" "lens-cover|1024x512" \
             "windshield-night|1024x512" "windshield-day|1024x512" "glass-droplets|1024x512" "paper|1024x512" \
             "full-physics|1024x512"; do
    for b in before now; do
      rm -rf "$sl/render-$b"
      "$(bin_of "$b")/raindrop-render" --cityscapes "$city" --split all --scene "${run%|*}" --size "${run#*|}" -q -j2 \
        --out "$sl/render-$b" >/dev/null
    done
    echo "$(basename "${run%|*}") at ${run#*|}: $(compare_renders "$sl/render-before" "$sl/render-now")"
  done | tee "$sl/differences.txt"
  # Both fast paths against the 256-ray aperture reference (the same drops), at 2048x1024 and 1024x512.
  edited_scene 's/"defocus": "layered"/"defocus": "aperture", "aperture_samples": 256/' "$sl/windshield-f2.json" \
    >"$sl/windshield-f2-reference.json"
  for size in native 1024x512; do
    for b in reference before now; do
      scene="$sl/windshield-f2.json"
      [[ $b == reference ]] && scene="$sl/windshield-f2-reference.json"
      rm -rf "$sl/$b-$size"
      "$(bin_of "$b")/raindrop-render" --cityscapes "$city" --split all --scene "$scene" --size "$size" -q -j2 \
        --out "$sl/$b-$size" >/dev/null
    done
    "$py" - "$sl/reference-$size" "$sl/before-$size" "$sl/now-$size" <<'PY'
import sys, glob, os, json
import cv2, numpy as np
ref, fasts = sys.argv[1], sys.argv[2:]
def drops(d):
    return [[(x["center_cm"], x["footprint_radius_cm"], x["contact_angle_deg"]) for x in json.loads(l)["drops"]]
            for l in open(os.path.join(d, "manifest.jsonl"))]
for f in fasts:
    assert drops(ref) == drops(f), f"{f}: not the reference's drops"
    sq = csq = n = worst = 0
    for p in sorted(glob.glob(os.path.join(ref, "rainy", "*.png"))):
        name = os.path.basename(p)
        r = cv2.imread(p).astype(float)
        a = cv2.imread(os.path.join(f, "rainy", name)).astype(float)
        ra = cv2.imread(os.path.join(ref, "alpha", name), cv2.IMREAD_UNCHANGED).astype(float) / 65535
        fa = cv2.imread(os.path.join(f, "alpha", name), cv2.IMREAD_UNCHANGED).astype(float) / 65535
        inside = (ra > 0) | (fa > 0)
        sq += ((r - a)[inside] ** 2).sum() / 3
        csq += ((ra - fa)[inside] ** 2).sum()
        n += inside.sum()
        worst = max(worst, np.abs(r - a).max())
    print(f"{os.path.basename(f)}: against the 256-ray reference, RMSE {np.sqrt(sq / n):.3f} levels inside either "
          f"coverage, worst {worst:.0f}; coverage RMS {np.sqrt(csq / n) * 255:.2f}/255")
PY
    rm -rf "$sl/reference-$size" "$sl/before-$size" "$sl/now-$size"
  done | tee "$sl/against-reference.txt"
  for r in 1 2 3; do
    for b in before now; do
      echo "$b round $r"
      "$(bin_of "$b")/raindrop-bench" render --sections camera --lens-size 2048x1024 --frames 3 --repeats 2 2>/dev/null |
        grep -E '^\| (paper|lens-cover|windshield-day|glass)' | grep -v aperture
    done
  done | tee "$sl/camera-2048.txt"
  for r in 1 2 3; do
    for b in before now; do
      rm -rf "$sl/e2e"
      start=$(date +%s%N)
      "$(bin_of "$b")/raindrop-render" --cityscapes "$city" --split all --scene "$sl/windshield-f2.json" --variants 2 -q \
        --out "$sl/e2e" >/dev/null
      echo "$b round $r: $(( ($(date +%s%N) - start) / 16000000 )) ms per frame (16 frames, 2048x1024, PNG written)"
    done
  done | tee "$sl/end-to-end.txt"
  rm -rf "$sl/render-before" "$sl/render-now" "$sl/e2e"
fi

if want dry; then
  # RESULTS 4.70: what raindrop-remove does to photographs without drops. Every change there is
  # damage: the output's PSNR-Y against its own input and the share of pixels marked
  # (text_negatives damage), on the clean images of the test sets (the real pairs' dry lens,
  # CamVid and Cityscapes frames), beside the real pairs' rainy test split scored as usual; the
  # default (float and int8, named, so that the figures do not depend on this CPU) and the
  # knobs a user could turn.
  router_sets
  windshield_1280_sets
  dr="$out/dry"
  mkdir -p "$dr"
  link_set data/real-pairs "$dr/pairs" test 0
  link_set data/test-sparse "$dr/sparse" - 0
  link_set data/test-wsday-1280x720 "$dr/camvid1280" - 0
  link_set data/test-size-1280x720 "$dr/cityscapes1280" - 0
  # scored SET LABEL FLAGS...: SET's rainy images through raindrop-remove FLAGS, scored against its
  # clean ones; damaged SET LABEL FLAGS...: its clean images through it, every change damage.
  scored() {
    local set="$1" label="$2"
    shift 2
    rm -rf "$dr/run"
    build/raindrop-remove "$dr/$set/rainy" "$dr/run/out" -q -j 2 "$@"
    $py -m raindrop_tools.score_outputs --data "$dr/$set" --outputs "$dr/run/out" --label "$label"
  }
  damaged() {
    local set="$1" label="$2"
    shift 2
    rm -rf "$dr/run"
    build/raindrop-remove "$dr/$set/clean" "$dr/run/out" --mask-dir "$dr/run/masks" -q -j 2 "$@"
    $py -m raindrop_tools.text_negatives damage --inputs "$dr/$set/clean" --outputs "$dr/run/out" \
      --masks "$dr/run/masks" --label "$label"
  }
  {
    for v in "float:--model-config compact-multiscale" "int8:--model-config compact-multiscale-int8" \
      "float-no-large-drops:--model-config compact-multiscale --no-large-drops" \
      "float-no-router:--model-config compact-multiscale --no-router" \
      "float-threshold-0.85:--model-config compact-multiscale --threshold 0.85" \
      "compact:--model-config compact" "paper:--model-config paper"; do
      name=${v%%:*}
      read -r -a flags <<<"${v#*:}"
      sets=(pairs)
      [[ $name == float || $name == int8 ]] && sets=(pairs sparse camvid1280 cityscapes1280)
      for set in "${sets[@]}"; do damaged "$set" "$name, $set without drops" "${flags[@]}"; done
      scored pairs "$name, pairs with drops" "${flags[@]}"
    done
  } | tee "$dr/damage.txt"
  rm -rf "$dr/run"
  # --keep-outside-mask (4.70): images the networks see at full size keep their pixels outside
  # the mask. The default and the default with it, on the sets that run at full size (the
  # 1280x720 ones go through the working scale, unchanged by it): validation, then test once;
  # the drop-free frames again; and the size gap of the held-out Cityscapes frames, float and
  # int8, that kept it from being the default.
  link_set data/val-sparse "$dr/val-sparse" - 0
  link_set data/val-windshield-sharp "$dr/val-ws" - 0
  link_set data/val-glass-plate "$dr/val-plate" - 0
  link_set data/real-pairs "$dr/pairs-train" train 0
  link_set data/test-windshield-sharp "$dr/test-ws" - 0
  {
    for set in pairs-train val-sparse val-ws val-plate pairs sparse test-ws; do
      for m in default kept; do
        flags=()
        [[ $m == kept ]] && flags=(--keep-outside-mask)
        scored "$set" "$m, $set" "${flags[@]}"
        if [[ $set == pairs || $set == sparse ]]; then damaged "$set" "$m, $set without drops" "${flags[@]}"; fi
      done
    done
    link_set data/test-size-512x288 "$dr/size512" - 0
    link_set data/test-size-1280x720 "$dr/size1280" - 0
    for models in compact-multiscale compact-multiscale-int8; do
      for m in default kept; do
        flags=()
        [[ $m == kept ]] && flags=(--keep-outside-mask)
        for set in size512 size1280; do scored "$set" "$models $m, $set" --model-config "$models" "${flags[@]}"; done
      done
    done
  } | tee "$dr/outside-mask.txt"
  # Where the default's RFN changes drop-free 512x256 frames outside the mask: the first 40 of
  # test-sparse's clean images (20 frames, two variants each).
  rm -rf "$dr/run" "$dr/first40" && mkdir -p "$dr/first40"
  ls "$dr/sparse/clean" | head -40 | while read -r f; do ln -s "$(realpath "$dr/sparse/clean/$f")" "$dr/first40/$f"; done
  build/raindrop-remove "$dr/first40" "$dr/run/out" --mask-dir "$dr/run/masks" -q -j 2
  $py - "$dr/first40" "$dr/run" <<'PY' | tee "$dr/outside-mask-pixels.txt"
import os, sys
import cv2, numpy as np
src, run = sys.argv[1:]
counts, worst, medians = [], [], []
for name in sorted(os.listdir(src)):
    a = cv2.imread(os.path.join(src, name)).astype(int)
    o = cv2.imread(os.path.join(run, "out", name)).astype(int)
    outside = cv2.imread(os.path.join(run, "masks", name), cv2.IMREAD_GRAYSCALE) == 0
    d = np.abs(a - o).max(axis=2) * outside
    changed = d > 0
    distance = cv2.distanceTransform(outside.astype(np.uint8), cv2.DIST_L2, 3)
    counts.append(int(changed.sum())); worst.append(int(d.max()))
    medians.append(float(np.median(distance[changed])) if changed.any() else 0.0)
print(f"{len(counts)} drop-free 512x256 frames, the default: pixels changed outside the mask {min(counts)}-{max(counts)} "
      f"(of {a.shape[0] * a.shape[1]}), by up to {min(worst)}-{max(worst)} levels, their median distance from the mask "
      f"{min(medians):.0f}-{max(medians):.0f} px")
PY
  rm -rf "$dr/run"
  # Can the program tell a photograph without drops by itself? The router's ten features
  # (detector_router.features) of both of the default's maps, rainy against dry: each feature
  # alone on the real pairs; a logistic gate fitted on the real pairs' train split and scored on
  # their test split (one camera); and one fitted on every validation set (each weighted alike)
  # and scored on the test sets and the 44 photographs, all of which hold drops.
  PYTHONPATH=tools $py - "$shared/real-raindrop" <<'PY' | tee "$dr/gate.txt"
import glob, json, os, sys
import cv2, numpy as np, onnxruntime as ort
from raindrop_tools.detector_router import features, working_copy
opts = ort.SessionOptions()
opts.intra_op_num_threads = 2
rdn = ort.InferenceSession("models/compact-multiscale/rdn.onnx", opts)
def feats(paths):
    out = []
    for p in paths:
        small = working_copy(cv2.imread(p)[:, :, ::-1])
        h, w = small.shape[:2]
        x = np.zeros((1, 3, (h + 7) // 8 * 8, (w + 7) // 8 * 8), np.float32)
        x[0, :, :h, :w] = small.transpose(2, 0, 1) / 255.0
        out.append(np.concatenate([features(m[0, 0, :h, :w]) for m in rdn.run(None, {"image": x})]))
    return np.array(out)
def pair(d, keep=lambda name: True):
    names = [n for n in sorted(os.listdir(f"data/{d}/rainy")) if keep(n)]
    return feats([f"data/{d}/rainy/{n}" for n in names]), feats([f"data/{d}/clean/{n}" for n in names])
def auc(score, y):
    r, c = score[y == 1], score[y == 0]
    return np.mean(r[:, None] > c[None, :]) + 0.5 * np.mean(r[:, None] == c[None, :])
def fit(sets):  # logistic regression, each set weighted alike, a small L2 penalty
    X = np.vstack([np.vstack(rc) for rc in sets])
    y = np.concatenate([np.r_[np.ones(len(r)), np.zeros(len(c))] for r, c in sets])
    wt = np.concatenate([np.full(len(r) + len(c), 1.0 / (len(r) + len(c))) for r, c in sets])
    wt /= wt.mean()
    mu, sd = X.mean(0), X.std(0) + 1e-9
    Z, w, b = (X - mu) / sd, np.zeros(X.shape[1]), 0.0
    for _ in range(20000):
        g = wt * (1 / (1 + np.exp(-(Z @ w + b))) - y)
        w -= 0.3 * ((Z * g[:, None]).mean(0) + 1e-3 * w)
        b -= 0.3 * g.mean()
    return lambda F: ((F - mu) / sd) @ w + b
test_groups = tuple(json.load(open("data/real-pairs/realpairs.json"))["groups"]["test"])  # robotcar_i<k>, crops _t<n>
pairs_train = pair("real-pairs", lambda n: not n.startswith(tuple(g + "_" for g in test_groups)))
pairs_test = pair("real-pairs", lambda n: n.startswith(tuple(g + "_" for g in test_groups)))
names = ["P>0.3", "0.05<P<=0.3", "mean P", "P>0.02"] + [f"{k}@{t}" for t in (0.05, 0.15, 0.3) for k in ("small parts", "median part")]
X = np.vstack([*pairs_train, *pairs_test])
y = np.r_[np.ones(len(pairs_train[0])), np.zeros(len(pairs_train[1])), np.ones(len(pairs_test[0])), np.zeros(len(pairs_test[1]))]
print("real pairs, rainy against dry, each feature of the main map alone: AUC " +
      ", ".join(f"{n} {max(auc(X[:, i], y), 1 - auc(X[:, i], y)):.2f}" for i, n in enumerate(names)))
gate = fit([pairs_train])
r, c = gate(pairs_test[0]), gate(pairs_test[1])
print(f"gate fitted on the real pairs' train split, on their test split: AUC {auc(np.r_[r, c], np.r_[np.ones(len(r)), np.zeros(len(c))]):.2f}; "
      + ", ".join(f"keeping {k:.0%} of the rainy images it passes over {np.mean(c < np.quantile(r, 1 - k)):.0%} of the dry ones" for k in (0.95, 0.99)))
val = {d: pair(d) for d in ("val-sparse", "val-wsday-1280x720", "val-ws-1280x720", "val-glass-plate", "val-size-1280x720")}
val["real-pairs train split"] = pairs_train
test = {d: pair(d) for d in ("test-sparse", "test-windshield-sharp", "test-ws-1280x720", "test-wsday-1280x720", "test-size-1280x720")}
test["real-pairs test split"] = pairs_test
photos = sorted(glob.glob(os.path.join(sys.argv[1], "*")))
gate_all = fit(list(val.values()))
photo_scores = gate_all(feats(photos))
for q in (0.0, 0.01):  # below every validation rainy image, and below all but 1% of them
    rainy_val = np.concatenate([gate_all(r) for r, _ in val.values()])
    th = rainy_val.min() if q == 0 else np.quantile(rainy_val, q)
    print(f"gate fitted on every validation set, threshold {'below every' if q == 0 else 'at the 1st percentile of'} validation rainy image:")
    for d, (r, c) in {**val, **test}.items():
        print(f"  {d}: rainy images passed over {np.mean(gate_all(r) < th):.1%}, dry ones {np.mean(gate_all(c) < th):.1%}")
    print(f"  the 44 photographs: {np.sum(photo_scores < th)} passed over: "
          + " ".join(os.path.basename(p) for p, v in zip(photos, photo_scores) if v < th))
PY
fi

if want wetgate; then
  # RESULTS 4.72: a camera's wet gate (raindrop_tools.wet_gate, raindrop-remove --wet-gate) fitted
  # on the real pairs' train split (wet lens: rainy/, dry lens: clean/, as whole frames) and run
  # on their test split, for three shares of wet training frames kept; the default (int8 and
  # float, named) without a gate beside it. Then the same gate on the 44 photographs of other
  # cameras, all of which hold drops.
  wg="$out/wetgate"
  rm -rf "$wg" && mkdir -p "$wg"
  $py - "$wg" <<'PY'
import json, os, sys
wg = sys.argv[1]
test = tuple(g + "_" for g in json.load(open("data/real-pairs/realpairs.json"))["groups"]["test"])
for name in sorted(os.listdir("data/real-pairs/rainy")):
    split = "test" if name.startswith(test) else "train"
    for kind, src in (("wet", "rainy"), ("dry", "clean")):
        os.makedirs(f"{wg}/{split}/{kind}", exist_ok=True)
        os.symlink(os.path.abspath(f"data/real-pairs/{src}/{name}"), f"{wg}/{split}/{kind}/{name}")
PY
  # judged RUN: the test split's wet and dry frames scored against the clean lens (wet) and
  # against themselves (dry: every change is damage).
  judged() {
    PYTHONPATH=tools $py - "$wg" "$1" <<'PY'
import os, sys
import numpy as np
from raindrop_tools import metrics
from raindrop_tools.imageio import read_rgb
wg, run = sys.argv[1:]
def y(a): return metrics.luma(metrics.crop_to_multiple(a))
names = sorted(os.listdir(f"{wg}/test/wet"))
clean = {n: read_rgb(f"{wg}/test/dry/{n}") for n in names}
rainy = {n: read_rgb(f"{wg}/test/wet/{n}") for n in names}
out = {n: read_rgb(f"{wg}/{run}/wet/{n}") for n in names}
dry = {n: read_rgb(f"{wg}/{run}/dry/{n}") for n in names}
gain = np.mean([metrics.psnr(y(out[n]), y(clean[n])) - metrics.psnr(y(rainy[n]), y(clean[n])) for n in names])
wet_left = sum(np.array_equal(out[n], rainy[n]) for n in names)
left = [np.array_equal(dry[n], clean[n]) for n in names]
changed = [n for n, s in zip(names, left) if not s]
mse = np.mean([np.mean((y(dry[n]).astype(float) - y(clean[n])) ** 2) for n in names])
marked = np.mean([np.mean(read_rgb(f"{wg}/{run}/dry-masks/{n}")[..., 0] > 0) for n in names])
print(f"| {run} | {gain:+.2f} | {wet_left} of {len(names)} | {sum(left)} of {len(names)} | "
      f"{np.mean([metrics.psnr(y(dry[n]), y(clean[n])) for n in changed]) if changed else float('inf'):.2f} | "
      f"{10 * np.log10(255 ** 2 / mse):.2f} | {marked:.1%} |")
PY
  }
  {
    echo "| run | wet test split: gain dB | wet frames written as they were | dry frames written as they were | the other dry frames: PSNR-Y against their input | all dry frames pooled: PSNR-Y | dry: marked |"
    echo "| --- | ---: | ---: | ---: | ---: | ---: | ---: |"
    for m in compact-multiscale-int8 compact-multiscale; do
      for keep in none 1.0 0.95 0.9; do
        run="$m-$keep"
        flags=(--model-config "$m")
        if [[ $keep != none ]]; then
          PYTHONPATH=tools $py -m raindrop_tools.wet_gate fit --models "models/$m" --wet "$wg/train/wet" \
            --dry "$wg/train/dry" --keep-wet "$keep" --out "$wg/$run.gate" >&2
          flags+=(--wet-gate "$wg/$run.gate")
        fi
        for kind in wet dry; do
          build/raindrop-remove "$wg/test/$kind" "$wg/$run/$kind" --mask-dir "$wg/$run/$kind-masks" -q -j 2 "${flags[@]}"
        done
        judged "$run"
      done
    done
  } | tee "$wg/scores.txt"
  # The gate of one camera on the others: the 44 photographs, every one with drops.
  for keep in 1.0 0.9; do
    PYTHONPATH=tools $py -m raindrop_tools.wet_gate judge --gate "$wg/compact-multiscale-int8-$keep.gate" \
      --models models/compact-multiscale-int8 "$shared"/real-raindrop/* >"$wg/photos-$keep.txt"
    echo "the gate kept at $keep on the 44 photographs: $(grep -c ' dry$' "$wg/photos-$keep.txt") judged dry" | tee -a "$wg/scores.txt"
  done
  # What a judged frame costs: the test split's dry frames, with and without the gate, in turn.
  for round in 1 2 3; do
    for g in none gate; do
      flags=(--model-config compact-multiscale-int8)
      [[ $g == gate ]] && flags+=(--wet-gate "$wg/compact-multiscale-int8-1.0.gate")
      s=$(date +%s.%N)
      build/raindrop-remove "$wg/test/dry" "$wg/timing" -q -j 2 "${flags[@]}"
      echo "round $round, $g: $(echo "($(date +%s.%N) - $s) * 1000 / 50" | bc -l | cut -c1-5) ms per dry 256x256 frame (folder of 50)"
    done
  done | tee -a "$wg/scores.txt"
  # sheet.png (the int8 default's gate kept at 1.0): each row the frame | the default's output
  # without the gate | the other lens; the wet frames it wrote as they were, then three dry frames
  # it judged dry and three it judged wet.
  $py - "$wg" <<'PY'
import os, sys
import cv2, numpy as np
wg = sys.argv[1]
run, base = f"{wg}/compact-multiscale-int8-1.0", f"{wg}/compact-multiscale-int8-none"
names = sorted(os.listdir(f"{wg}/test/wet"))
same = lambda a, b: np.array_equal(cv2.imread(a), cv2.imread(b))
rows = [("wet, judged dry", n, "wet", "dry") for n in names if same(f"{wg}/test/wet/{n}", f"{run}/wet/{n}")]
dry = [n for n in names if same(f"{wg}/test/dry/{n}", f"{run}/dry/{n}")]
rows += [("dry, judged dry", n, "dry", "wet") for n in dry[:3]]
rows += [("dry, judged wet", n, "dry", "wet") for n in names if n not in dry][:3]
sheet = []
for label, n, kind, other in rows:
    r = np.hstack([cv2.imread(f"{wg}/test/{kind}/{n}"), cv2.imread(f"{base}/{kind}/{n}"), cv2.imread(f"{wg}/test/{other}/{n}")])
    cv2.putText(r, f"{label}: {n}", (4, 14), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 255, 255), 1)
    sheet.append(r)
cv2.imwrite(f"{wg}/sheet.png", np.vstack(sheet))
PY
fi

if want evalprogram; then
  # docs/RESULTS.md 4.75: the held-out real pairs scored by evaluate through raindrop-remove as a
  # user runs it (--program), beside the networks' single pass, with the report's contact sheets
  # (input | mask | output | clean) in $out/evalprogram/<run>/sheets.
  ep="$out/evalprogram"
  mkdir -p "$ep"
  $py -m raindrop_tools.evaluate --real-pairs "$shared/real-pairs" --program build/raindrop-remove \
    --out "$ep/program-default" --no-progress | tee "$ep/program-default.txt"
  $py -m raindrop_tools.evaluate --real-pairs "$shared/real-pairs" --program build/raindrop-remove \
    --models models/compact-multiscale --out "$ep/program-float" --no-progress | tee "$ep/program-float.txt"
  $py -m raindrop_tools.evaluate --real-pairs "$shared/real-pairs" --models models/compact-multiscale \
    --out "$ep/single-pass-float" --no-progress | tee "$ep/single-pass-float.txt"
fi

if want photostally; then
  # docs/RESULTS.md 4.76: the 44 photographs through the default and through `--dilation 7
  # --fine-drops`, each with a sheet per photograph (input | mask tinted red | output, full
  # resolution) to judge by eye, drop kind by drop kind, as that section's table does.
  pt="$out/photostally"
  rm -rf "$pt" && mkdir -p "$pt"
  build/raindrop-remove "$shared/real-raindrop" "$pt/default" --mask-dir "$pt/default-masks" -q
  build/raindrop-remove "$shared/real-raindrop" "$pt/dilation7-finedrops" --mask-dir "$pt/dilation7-finedrops-masks" \
    -q --dilation 7 --fine-drops
  $py - "$shared/real-raindrop" "$pt" <<'PY'
import sys, cv2, numpy as np
from pathlib import Path
photos, pt = Path(sys.argv[1]), Path(sys.argv[2])
for run in ("default", "dilation7-finedrops"):
    # What raindrop-remove wrote: every image under the folder, subfolders included, by its
    # relative name (it skips hidden files and what it cannot read, and so does this).
    for out_path in sorted(p for p in (pt / run).rglob("*") if p.is_file()):
        rel = out_path.relative_to(pt / run)
        rgb, out = cv2.imread(str(photos / rel)), cv2.imread(str(out_path))
        mask = cv2.imread(str(pt / f"{run}-masks" / rel.with_suffix(".png")), cv2.IMREAD_GRAYSCALE)
        if rgb is None or out is None or mask is None or rgb.shape != out.shape:
            print("no sheet for", rel)
            continue
        tinted = rgb.copy()
        tinted[mask > 0] = (0.5 * tinted[mask > 0] + (0, 0, 127)).astype(np.uint8)
        sheet = pt / f"{run}-sheets" / rel.with_suffix(".png")
        sheet.parent.mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(sheet), np.hstack([rgb, tinted, out]))
print("sheets:", pt)
PY
fi

if want largedetail; then
  # docs/RESULTS.md 4.77: the input's fine detail given back under the coarse pass's fill
  # (--large-drop-detail, 0.5 since). The validation sets of the default (default_sets, with
  # the lens-cover discs at 720x480 where rendered) with 0 (before) and 0.5; the test sets once;
  # the 44 photographs with both, and the photographs whose outputs change.
  default_sets
  ld="$out/largedetail"
  mkdir -p "$ld"
  vals=("${router_vals[@]}" val-ws-1280x720:-:0 val-wsday-1280x720:-:0 val-size-1280x720:-:0 val-size-512x288:-:0
        val-glass-plate:-:0)
  [[ -f data/val-lens-discs-720x480/manifest.jsonl ]] && vals+=(val-lens-discs-720x480:-:0)
  for g in 0 0.5; do
    score_sets "$ld" "detail$g" "-j 2 --large-drop-detail $g" "${vals[@]}"
  done | tee "$ld/scores.txt"
  for g in 0 0.5; do
    score_sets "$ld" "test-detail$g" "-j 2 --large-drop-detail $g" "${router_tests[@]}" test-ws-1280x720:-:0 \
      test-wsday-1280x720:-:0
  done | tee "$ld/test.txt"
  router_photos "$ld" detail0 --large-drop-detail 0
  router_photos "$ld" detail0.5 --large-drop-detail 0.5
  photos_changed "$ld/photos-detail0.5/removed" "$ld/photos-detail0/removed" | tee "$ld/photos-changed.txt"
fi
