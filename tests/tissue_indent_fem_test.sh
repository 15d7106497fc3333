#!/bin/sh
# `bisturi tissue indent --model volume` against a CalculiX reference (tests/data/fem):
#   tissue_indent_fem_test.sh BISTURI REFERENCE.json POINTS TOLERANCE [bisturi options...]
# runs the volume model on the reference's first POINTS depths (its depths are evenly spaced
# from its first) and fails when a force is off the reference's by more than TOLERANCE (a
# fraction), or the curve does not grow with depth.
set -u
bisturi="$1" reference="$2" points="$3" tolerance="$4"
shift 4
fail() { echo "FAIL: $*"; exit 1; }
array() {  # the numbers of JSON array "$1" in file "$2", one per line
  tr -d ' \n' < "$2" | sed -n "s/.*\"$1\":\[\([^]]*\)\].*/\1/p" | tr ',' '\n'
}
shape=$(tr -d ' \n' < "$reference" | sed -n 's/.*"shape":"\([a-z]*\)".*/\1/p')
size=$(tr -d ' \n' < "$reference" | sed -n 's/.*"size_mm":\([0-9.]*\).*/\1/p')
probe=$(tr -d ' \n' < "$reference" | sed -n 's/.*"probe_radius_mm":\([0-9.]*\).*/\1/p')
youngs=$(tr -d ' \n' < "$reference" | sed -n 's/.*"youngs_modulus_kPa":\([0-9.]*\).*/\1/p')
nu=$(tr -d ' \n' < "$reference" | sed -n 's/.*"poisson_ratio":\([0-9.]*\).*/\1/p')
depth=$(array depth_mm "$reference" | sed -n "${points}p")
[ -n "$depth" ] || fail "$reference has fewer than $points depths"
out=$(mktemp)
"$bisturi" tissue indent --model volume --shape "$shape" --size-mm "$size" \
  --youngs-kPa "$youngs" --poisson "$nu" --probe-radius-mm "$probe" --depth-mm "$depth" \
  --points "$points" --json "$@" > "$out" || fail "bisturi tissue indent exited with $?"
array force_N "$out" > "$out.got"
array fem_N "$reference" | head -n "$points" > "$out.want"
paste "$out.got" "$out.want" | awk -v tol="$tolerance" '
  { err = $1 / $2 - 1; printf "  %.5f N against %.5f N: %+.1f %%\n", $1, $2, 100 * err
    if (err > tol || err < -tol) bad = 1
    if (NR > 1 && $1 <= last) bad = 2
    last = $1 }
  END { exit bad }' || { rm -f "$out" "$out.got" "$out.want"; fail "off the reference or not growing"; }
grep -q '"converged": true' "$out" || fail "the static solve did not converge"
rm -f "$out" "$out.got" "$out.want"
echo "fem: ok"
