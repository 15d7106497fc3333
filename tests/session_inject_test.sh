#!/bin/sh
# A fault injected into a three-second default session (`bisturi run --inject FAULT@1.6`, during
# the grasp, while the fingers hold 0.8 N), as CTest runs it:
#   session_inject_test.sh BISTURI WORKDIR FAULT
# Every fault: report.json whole, the fault made, and what must follow it: the force at zero on
# every channel within 100 ms (tissue-hang, tissue-throw, device-unplug, render-throw: the
# session's ticks count the fade and the zero, the bound leaves room for a loaded machine; the
# fingers hold 0.8 N then in most runs, which the report's force_before_N says), the
# recording stopped and named (trace-disk-full), or a stalled disk that holds up nothing: the
# session completes and its recording replays exactly (trace-slow-disk). A device that holds off
# the host's write for 2 s (device-io-stall) gets the supervisor's zero past the stuck tick
# within the same 100 ms, and the session completes and replays exactly; a renderer stuck in a
# frame for 2 s (render-hang) holds the forces at zero from its display timeout on.
set -u
bisturi="$1"
work="$2/inject-$3"
fault="$3"
fail() { echo "FAIL: $fault: $*"; [ -f "$work/report.json" ] && cat "$work/report.json"; exit 1; }
rm -rf "$work" "$work.btrace"
mkdir -p "$work"
"$bisturi" run --duration 3 --eye-width 128 --eye-height 128 --no-openxr --out "$work" \
  --record "$work.btrace" --inject "$fault@1.6" > "$work.txt" 2>&1
status=$?
[ -s "$work/report.json" ] || { cat "$work.txt"; fail "no report.json (exit $status)"; }
report="$work/report.json"
value() { grep -o "\"$1\": [^,}]*" "$report" | head -1 | sed 's/.*: //'; }
ending=$(value ending | tr -d '"')
injected=$(value injected_s)
before=$(value force_before_N)
zero=$(value zero_after_ms)
[ "$injected" != null ] && [ -n "$injected" ] || fail "the fault was not made"
echo "$fault: ending $ending, injected at $injected s, $before N before, zero after $zero ms"
zero_within() {
  [ "$zero" != null ] || fail "the force never reached zero"
  awk -v z="$zero" 'BEGIN { exit !(z <= 100) }' || fail "zero after $zero ms (want within 100 ms)"
}
case "$fault" in
  tissue-hang)
    [ "$ending" = completed ] || fail "ending $ending, want completed"
    [ "$(value stale_ticks)" -gt 100 ] || fail "no stale ticks: the tissue did not hang"
    zero_within ;;
  device-unplug)
    [ "$ending" = completed ] || fail "ending $ending, want completed"
    [ "$(value haptic_device_lost_s)" != null ] || fail "the report does not say the device was lost"
    zero_within ;;
  tissue-throw|render-throw)
    [ "$ending" = error ] || fail "ending $ending, want error"
    [ "$status" = 1 ] || fail "exit $status, want 1"
    grep -q "injected fault: $fault" "$report" || fail "the error does not name the fault"
    zero_within ;;
  render-hang)
    # A frozen picture: the forces stop once the renderer has not come round for the report's
    # display timeout (1 s with frames going to files), and the session goes on when it does.
    [ "$ending" = completed ] || fail "ending $ending, want completed"
    [ "$(value display_stalls)" -ge 1 ] || fail "the report counts no display stall"
    [ "$zero" != null ] || fail "the force never reached zero"
    timeout_ms=$(value display_timeout_ms)
    awk -v z="$zero" -v t="$timeout_ms" 'BEGIN { exit !(z <= t + 100) }' ||
      fail "zero after $zero ms (want within the $timeout_ms ms display timeout + 100 ms)"
    "$bisturi" replay "$work.btrace" --json > "$work.replay.json" 2>&1 ||
      { cat "$work.replay.json"; fail "the recording does not replay"; }
    grep -q '"force_mismatches": 0' "$work.replay.json" || fail "the replay's forces differ" ;;
  device-io-stall)
    [ "$ending" = completed ] || fail "ending $ending, want completed"
    [ "$(value supervisor_zeros)" -ge 1 ] || fail "the supervisor did not zero the stuck tick"
    zero_within
    "$bisturi" replay "$work.btrace" --json > "$work.replay.json" 2>&1 ||
      { cat "$work.replay.json"; fail "the recording does not replay"; }
    grep -q '"force_mismatches": 0' "$work.replay.json" || fail "the replay's forces differ" ;;
  trace-disk-full)
    [ "$ending" = completed ] || fail "ending $ending, want completed"
    grep -q '"recording_error": ".*No space left on device' "$report" ||
      fail "the report does not say why the recording stopped" ;;
  trace-slow-disk)
    [ "$ending" = completed ] || fail "ending $ending, want completed"
    grep -q '"recording_error": null' "$report" || fail "the recording stopped"
    "$bisturi" replay "$work.btrace" --json > "$work.replay.json" 2>&1 ||
      { cat "$work.replay.json"; fail "the recording does not replay"; }
    grep -q '"force_mismatches": 0' "$work.replay.json" || fail "the replay's forces differ" ;;
  *) fail "unknown fault" ;;
esac
echo "inject $fault: ok"
