#!/bin/sh
# Builds the tests with sanitizers in their own build folders and runs them:
#   tools/sanitize.sh tsan [-j N]   ThreadSanitizer: the threaded pieces (the triple buffer, the
#                                   tissue thread, the step team, the fibers, the haptic loop),
#                                   then two live sessions with faults injected (TSAN_LIVE=0: not)
#   tools/sanitize.sh asan [-j N]   AddressSanitizer + UndefinedBehaviorSanitizer: the unit tests
#   tools/sanitize.sh all  [-j N]   both
# Folders: build-tsan/, build-asan/ (next to build/). Only the targets run are built. Override the
# lists with TSAN_TESTS / ASAN_TESTS (space-separated target names). Any report fails the run
# (halt_on_error): the exit status is non-zero when a build, a test or a sanitizer fails.
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
mode="${1:-all}"
jobs=2
if [ "${2:-}" = "-j" ] && [ -n "${3:-}" ]; then jobs="$3"; fi

# name:gtest-filter (the filter keeps a big suite to its threaded tests). The haptic loop's
# failed-trace-write test and the trace's killed-writer test fork a threaded process:
# ThreadSanitizer cannot follow a fork of a threaded process ("starting new threads after
# multi-threaded fork is not supported").
tsan_default="session_test:*TripleBuffer* session_tissue_thread_test sim_threads_test \
sim_fiber_test session_haptic_loop_test:-*AFailedTraceWrite* trace_test:-*Killed* \
devices_test:*Preempt*:*StuckWrite*"
asan_default="devices_test devices_spec_test devices_usb_async_test devices_descriptor_files_test \
devices_sample_test devices_example_test trace_test session_devices_test dlfl_operators_test \
dlfl_figures_test dlfl_random_test mesh_io_test polygon_import_test oriented_builder_test \
volume_io_test bono_octree_test segmentation_test marching_cubes_test lod_test sim_volume_test \
sim_volume_body_test sim_blood_test devices_usb_endpoints_test session_two_hands_test \
session_bleeding_test session_device_check_test session_heartbeat_test"

configure() {  # folder, sanitizer flags
  mkdir -p "$here/$1"
  cmake -S "$here" -B "$here/$1" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_CXX_FLAGS="$2 -fno-omit-frame-pointer" \
    -DCMAKE_EXE_LINKER_FLAGS="$2" -DCMAKE_SHARED_LINKER_FLAGS="$2" \
    -DBISTURI_BUILD_TESTS=ON -DBISTURI_BUILD_BENCHMARKS=OFF \
    -DCMAKE_GTEST_DISCOVER_TESTS_DISCOVERY_MODE=PRE_TEST > "$here/$1/configure.log"
}

run_suite() {  # folder, list of target[:filter]
  folder="$1"
  shift
  targets=""
  for entry in "$@"; do
    name=${entry%%:*}
    # Targets the tree does not have (yet) are skipped, named.
    if grep -q "bisturi_test($name)" "$here/tests/CMakeLists.txt" ||
       grep -rq "add_executable($name " "$here/devices"; then
      targets="$targets $name"
    else
      echo "sanitize: no test target $name here, skipped"
    fi
  done
  echo "sanitize: building$targets in $folder (-j$jobs)"
  # shellcheck disable=SC2086
  cmake --build "$here/$folder" -j"$jobs" --target $targets || return 1
  failed=0
  for entry in "$@"; do
    name=${entry%%:*}
    filter="*"
    [ "$entry" != "$name" ] && filter=${entry#*:}
    exe="$here/$folder/bin/$name"
    [ -x "$exe" ] || continue
    echo "sanitize: $folder: $name --gtest_filter=$filter"
    if ! "$exe" --gtest_filter="$filter" --gtest_brief=1 > "$here/$folder/$name.log" 2>&1; then
      failed=1
      echo "sanitize: FAILED: $name (log: $folder/$name.log)"
      tail -40 "$here/$folder/$name.log"
    fi
  done
  return $failed
}

run_live() {  # folder: live default sessions with the threads' faults injected
  folder="$1"
  echo "sanitize: building bisturi in $folder (-j$jobs)"
  cmake --build "$here/$folder" -j"$jobs" --target bisturi || return 1
  failed=0
  # The supervisor's zero past a stuck device write, a hung frame and a hung tissue step, a
  # stalled trace disk: every thread of a session and each path between them; then two hands
  # (the supervisor zeroing both) and a bleeding vessel (the blood stepped on the tissue thread,
  # drawn by the renderer).
  for faults in "--duration 3 --inject tissue-hang@0.5 --inject device-io-stall@0.9" \
                "--duration 3 --inject render-hang@0.8 --inject trace-slow-disk@1.0" \
                "$here/config/two_hands.toml --duration 3 --inject device-io-stall@1.5" \
                "$here/config/bleeding.toml --duration 8 --tissue-hz 500"; do
    name=_$(echo "$faults" | sed 's|.*/config/||' | tr -cs 'a-z0-9' '_')
    echo "sanitize: $folder: bisturi run $faults"
    # shellcheck disable=SC2086
    if ! "$here/$folder/bin/bisturi" run --eye-width 64 --eye-height 64 --no-openxr \
         --out "$here/$folder/live$name" --record "$here/$folder/live$name.btrace" $faults \
         > "$here/$folder/live$name.log" 2>&1 ||
       grep -q "ThreadSanitizer" "$here/$folder/live$name.log"; then
      failed=1
      echo "sanitize: FAILED: bisturi run $faults (log: $folder/live$name.log)"
      tail -40 "$here/$folder/live$name.log"
    fi
  done
  return $failed
}

status=0
if [ "$mode" = tsan ] || [ "$mode" = all ]; then
  configure build-tsan "-fsanitize=thread -g"
  export TSAN_OPTIONS="halt_on_error=1 second_deadlock_stack=1 ${TSAN_OPTIONS:-}"
  # shellcheck disable=SC2086
  run_suite build-tsan ${TSAN_TESTS:-$tsan_default} || status=1
  [ "${TSAN_LIVE:-1}" = 0 ] || run_live build-tsan || status=1
fi
if [ "$mode" = asan ] || [ "$mode" = all ]; then
  configure build-asan "-fsanitize=address,undefined -fno-sanitize-recover=undefined -g"
  export ASAN_OPTIONS="detect_leaks=1 ${ASAN_OPTIONS:-}" UBSAN_OPTIONS="print_stacktrace=1"
  # shellcheck disable=SC2086
  run_suite build-asan ${ASAN_TESTS:-$asan_default} || status=1
fi
[ "$status" -eq 0 ] && echo "sanitize: $mode: all passed"
exit "$status"
