#!/usr/bin/env bash
# Builds the mesh and volume reader fuzz targets (clang, libFuzzer, ASan + UBSan) and runs each
# for a bounded time. Fails on any crash, leak, timeout, out-of-memory or sanitizer report.
#
#   run_fuzzers.sh [--build-only | --no-build] [obj|ply|stl|off|nrrd|nifti|hid_descriptor|hid_report|trace ...]   (default: all)
#
#   BISTURI_FUZZ_BUILD    build folder (default: <repo>/build/fuzz)
#   BISTURI_FUZZ_SECONDS  seconds per target (default: 60)
#
# New inputs go to $BUILD/corpus/<format> (the seeds in tests/fuzz/corpus are only read), crash
# artifacts to $BUILD/artifacts/<format>/, each run's log to $BUILD/fuzz_read_<format>.log.
set -euo pipefail

here=$(cd "$(dirname "$0")" && pwd)
build=${BISTURI_FUZZ_BUILD:-$(cd "$here/../.." && pwd)/build/fuzz}
seconds=${BISTURI_FUZZ_SECONDS:-60}
build_step=1
run_step=1
formats=()
for arg in "$@"; do
  case "$arg" in
    --build-only) run_step=0 ;;
    --no-build) build_step=0 ;;
    obj | ply | stl | off | nrrd | nifti | hid_descriptor | hid_report | trace) formats+=("$arg") ;;
    *) echo "usage: $0 [--build-only | --no-build] [obj|ply|stl|off|nrrd|nifti|hid_descriptor|hid_report|trace ...]" >&2; exit 2 ;;
  esac
done
((${#formats[@]} > 0)) || formats=(obj ply stl off nrrd nifti hid_descriptor hid_report trace)
mkdir -p "$build"

if ((build_step)); then
  # ctest may start several of these at once: one builds, the others wait and find it done.
  exec 9>"$build/.build.lock"
  flock 9
  launcher=()
  if command -v ccache >/dev/null; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
  cmake -S "$here" -B "$build" -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=RelWithDebInfo "${launcher[@]}" >/dev/null
  cmake --build "$build" -j "$(nproc)"
  flock -u 9
fi
((run_step)) || exit 0

export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1:symbolize=1}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}
status=0
for format in "${formats[@]}"; do
  target="$build/fuzz_read_$format"
  [[ -x "$target" ]] || { echo "fuzz: $target is not built" >&2; exit 1; }
  mkdir -p "$build/corpus/$format" "$build/artifacts/$format"
  log="$build/fuzz_read_$format.log"
  start=$SECONDS
  if "$target" "$build/corpus/$format" "$here/corpus/$format" -dict="$here/dict/$format.dict" \
      -max_total_time="$seconds" -max_len=65536 -rss_limit_mb=2048 -timeout=10 \
      -artifact_prefix="$build/artifacts/$format/" -print_final_stats=1 >"$log" 2>&1; then
    runs=$(grep -o 'stat::number_of_executed_units: *[0-9]*' "$log" | grep -o '[0-9]*$' || true)
    echo "fuzz_read_$format: ok, ${runs:-?} inputs in $((SECONDS - start)) s"
  else
    echo "fuzz_read_$format: FAILED after $((SECONDS - start)) s; log $log, artifacts in $build/artifacts/$format/"
    grep -m 8 -E "ERROR|runtime error|SUMMARY|invariant broken|Test unit written" "$log" || true
    tail -n 40 "$log"
    status=1
  fi
done
exit $status
