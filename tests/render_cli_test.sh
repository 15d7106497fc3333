#!/bin/sh
# bisturi render SCENE as a user runs it: the liver scene's lesion and vein are culled as hidden
# inside the closed liver (occlusion) and, with the procedure's incision, as seen through no
# opening in the frames where the incision does not face the eyes (portal), never both; with
# --occlusion the depth test only adds to what is culled.
# $1: bisturi, $2: work folder, $3: the liver scene.
set -u
bisturi=$1
work=$2
scene=$3
fail() { echo "render-scene: FAILED: $*"; exit 1; }
rm -rf "$work" && mkdir -p "$work" || fail "no work folder $work"
culled() { tr -d ' \n' < "$1" | grep -o "\"$2\":[0-9.e+-]*" | head -n 1 | cut -d: -f2; }
"$bisturi" render "$scene" --out "$work/closed" --frames 8 --eye-width 64 --eye-height 64 \
  --json > "$work/closed.json" || fail "bisturi render exited with $?"
"$bisturi" render "$scene" --incision --out "$work/cut" --frames 8 --eye-width 64 \
  --eye-height 64 --json > "$work/cut.json" || fail "bisturi render --incision exited with $?"
grep -q '"solids": 4' "$work/closed.json" || fail "not the liver, the vessel and two inner structures"
awk -v o="$(culled "$work/closed.json" occlusion)" -v p="$(culled "$work/closed.json" portal)" \
  'BEGIN { exit !(o > 0 && p == 0) }' || fail "closed: occlusion $(culled "$work/closed.json" occlusion), portal $(culled "$work/closed.json" portal)"
awk -v o="$(culled "$work/cut.json" occlusion)" -v p="$(culled "$work/cut.json" portal)" \
  'BEGIN { exit !(o == 0 && p > 0) }' || fail "cut: occlusion $(culled "$work/cut.json" occlusion), portal $(culled "$work/cut.json" portal)"
# With the depth test too (--occlusion) the same levels are drawn: it can only move triangles
# from submitted to culled by occlusion.
"$bisturi" render "$scene" --occlusion --out "$work/depth" --frames 8 --eye-width 64 \
  --eye-height 64 --json > "$work/depth.json" || fail "bisturi render --occlusion exited with $?"
awk -v a="$(culled "$work/depth.json" occlusion)" -v b="$(culled "$work/closed.json" occlusion)" \
  -v ta="$(culled "$work/depth.json" triangles_per_frame)" \
  -v tb="$(culled "$work/closed.json" triangles_per_frame)" \
  'BEGIN { exit !(a >= b && ta + a == tb + b) }' ||
  fail "--occlusion: $(culled "$work/depth.json" triangles_per_frame) submitted and $(culled "$work/depth.json" occlusion) hidden, against $(culled "$work/closed.json" triangles_per_frame) and $(culled "$work/closed.json" occlusion)"
"$bisturi" render --phantom sphere --incision --out "$work/x" > "$work/bad.txt" 2>&1 &&
  fail "--incision on a phantom was taken"
grep -q "scene files" "$work/bad.txt" || { cat "$work/bad.txt"; fail "--incision on a phantom: no reason given"; }
echo "render-scene: ok"
