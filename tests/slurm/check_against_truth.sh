#!/bin/sh
# Checks a gathered cohort table against the phantoms' truth (`bisturi cohort phantoms`):
# every section's centre within CENTRE_MM of the true axis and its mean diameter within
# DIAMETER_MM of twice the true radius at its nearest axis point; every case ok, with its
# branches (3 for a bifurcation, else 1) and at least 5 sections. Prints the accuracy per case.
# usage: check_against_truth.sh MANIFEST.csv TRUTH.csv COHORT.csv COHORT_CASES.csv [DIAMETER_MM] [CENTRE_MM]
set -eu
manifest=$1 truth=$2 sections=$3 cases=$4 tol_d=${5:-0.05} tol_c=${6:-0.4}
awk -F, -v tol_d="$tol_d" -v tol_c="$tol_c" '
  FNR == 1 { file++; next }
  file == 1 { shape[$1] = $3; wanted++; next }
  file == 2 { n = ++pieces[$1]; ax[$1, n] = $3; ay[$1, n] = $4; az[$1, n] = $5
              bx[$1, n] = $6; by[$1, n] = $7; bz[$1, n] = $8; ra[$1, n] = $9; rb[$1, n] = $10; next }
  file == 3 {
    c = $1; px = $5; py = $6; pz = $7; d = $11; best = -1
    for (k = 1; k <= pieces[c]; k++) {
      ux = bx[c, k] - ax[c, k]; uy = by[c, k] - ay[c, k]; uz = bz[c, k] - az[c, k]
      t = ((px - ax[c, k]) * ux + (py - ay[c, k]) * uy + (pz - az[c, k]) * uz) / (ux * ux + uy * uy + uz * uz)
      if (t < 0) t = 0; if (t > 1) t = 1
      qx = ax[c, k] + t * ux - px; qy = ay[c, k] + t * uy - py; qz = az[c, k] + t * uz - pz
      dist = sqrt(qx * qx + qy * qy + qz * qz)
      if (best < 0 || dist < best) { best = dist; r = ra[c, k] + t * (rb[c, k] - ra[c, k]) }
    }
    if (best < 0) { print "no truth for case " c; bad = 1; next }
    e = d - 2 * r; if (e < 0) e = -e
    count[c]++; sum[c] += e; if (e > emax[c]) emax[c] = e; if (best > cmax[c]) cmax[c] = best
    if (e > tol_d || best > tol_c) { printf "case %s: section at (%s, %s, %s): diameter %s, true %.4f, %.3f mm off the axis\n", c, px, py, pz, d, 2 * r, best; bad = 1 }
    next
  }
  file == 4 {
    c = $3; seen++
    if ($4 != "ok") { print "case " c ": status " $4 " (" $5 ")"; bad = 1; next }
    want = shape[c] == "bifurcating" ? 3 : 1
    if ($6 != want) { print "case " c ": " $6 " branches, expected " want; bad = 1 }
    if ($9 < 5) { print "case " c ": only " $9 " sections"; bad = 1 }
  }
  END {
    printf "%-10s %-12s %8s %14s %14s %14s\n", "case", "shape", "sections", "centre max mm", "|d err| mean", "|d err| max"
    for (c in shape) printf "%-10s %-12s %8d %14.4f %14.4f %14.4f\n", c, shape[c], count[c], cmax[c], count[c] ? sum[c] / count[c] : 0, emax[c]
    if (seen != wanted) { print "cases table: " seen " cases, manifest: " wanted; bad = 1 }
    exit bad
  }' "$manifest" "$truth" "$sections" "$cases"
