#!/bin/sh
# bisturi device list|describe|check and bisturi trace dump, as CTest runs them:
#   device_cli_test.sh BISTURI WORKDIR list|describe|malformed|dump|check|udev HID_DATA_DIR
set -u
bisturi="$1"
work="$2"
mode="$3"
data="$4"
fail() { echo "FAIL: $*"; exit 1; }
mkdir -p "$work"
case "$mode" in
  list)
    # Works with nothing connected (these machines have no USB): an empty list, exit 0.
    out=$("$bisturi" device list --json) || fail "device list exited $?"
    echo "$out" | grep -q '"devices": \[' || { echo "$out"; fail "no devices array"; }
    echo "$out" | grep -q '"name": "hid-glove"' || fail "the registered drivers are not listed"
    # The template driver is not a product's: it stays out of the built-in registry.
    echo "$out" | grep -q '"name": "sample-pinch"' && fail "the template driver is registered"
    # Each driver with its ids, twin and channel roles: what an integrator needs to pick one.
    echo "$out" | tr -d ' \n' | grep -q '"name":"vendor-arm","summary":"[^"]*","twin":true,"usb_ids":\["0x1209:0xB157"\]' ||
      fail "vendor-arm is listed without its ids or its twin"
    echo "$out" | tr -d ' \n' | grep -q '"buttons":\["grasp","cut"\],"channels":\["vector"\]' ||
      fail "vendor-arm is listed without its button roles"
    echo "$out" | tr -d ' \n' | grep -q '"channels":\["finger0"\],"class":"haptic-glove","name":"openxr-controller"' ||
      fail "openxr-controller is listed without its channel roles"
    "$bisturi" device list > /dev/null || fail "device list (text) exited $?"
    echo "list: ok"
    ;;
  check)
    # The arm against its twin through the guard: its grip grasps, its second button cuts, the
    # force stays within the cap asked for; a driver without a twin is refused (exit 2).
    out=$("$bisturi" device check vendor-arm --seconds 2 --max-force-N 2 --json) ||
      { echo "$out"; fail "device check exited $?"; }
    echo "$out" | grep -q '"passed": true' || { echo "$out"; fail "the arm's check did not pass"; }
    echo "$out" | grep -q '"kind": "grasp"' || fail "the arm's grip grasped nothing"
    echo "$out" | grep -q '"kind": "cut"' || fail "the arm's second button cut nothing"
    echo "$out" | grep -q '"limit_N": 2.0' || fail "the cap is not the channel's limit"
    "$bisturi" device check hid-glove --seconds 1 > "$work/check.txt" 2>&1
    grep -q 'finger 2' "$work/check.txt" || { cat "$work/check.txt"; fail "no finger channels"; }
    "$bisturi" device check openxr-controller > "$work/check.txt" 2>&1
    [ $? -eq 2 ] || fail "a driver without a twin was checked"
    grep -q 'no simulated twin' "$work/check.txt" || { cat "$work/check.txt"; fail "no reason"; }
    echo "check: ok"
    ;;
  udev)
    # Rules from the registry: the vendor arm's raw USB node by its ids, in the lower-case hex
    # sysfs gives (udev compares text), for the seat's user and plugdev.
    out=$("$bisturi" device udev-rules) || fail "device udev-rules exited $?"
    echo "$out" | grep -q '^SUBSYSTEM=="usb", ATTR{idVendor}=="1209", ATTR{idProduct}=="b157", MODE="0660", GROUP="plugdev", TAG+="uaccess"$' ||
      { echo "$out"; fail "no rule for the vendor arm"; }
    echo "$out" | grep -q '^# hid-glove' || fail "the HID glove is not mentioned"
    echo "$out" | grep -o 'id[VP][a-z]*}=="[^"]*"' | grep -q '[A-F]' &&
      fail "upper-case ids: udev would not match them"
    echo "udev: ok"
    ;;
  describe)
    out=$("$bisturi" device describe "$data/sony_dualshock4_v2_usb.bin") || fail "exit $?"
    echo "$out" | grep -q "input report 1: 504 bits, 64 bytes on the wire" || { echo "$out"; fail "DS4 input"; }
    echo "$out" | grep -q "output report 5: 248 bits, 32 bytes on the wire" || fail "DS4 output"
    echo "$out" | grep -q "hid-glove: cannot use it: its application collection is 0x0001:0x0005" ||
      fail "no reason why the glove driver cannot use a game pad"
    json=$("$bisturi" device describe "$data/hid_boot_mouse.bin" --json) || fail "exit $?"
    echo "$json" | tr -d ' \n' | grep -q '"reports":\[{"bits":24,"bytes":3,"fields":\[' ||
      { echo "$json"; fail "mouse report in JSON"; }
    echo "$json" | tr -d ' \n' | grep -q '"id":0,"type":"input"}\]' || fail "mouse report id/type"
    json=$("$bisturi" device describe "$data/constructed_wide_and_zero_size.bin" --json) || fail "exit $?"
    echo "$json" | grep -q "report size 0" || fail "no warning for Report Size 0"
    echo "$json" | grep -q "wider than 32 bits" || fail "no warning for a 64-bit field"
    "$bisturi" device describe --help | grep -q "DESCRIPTOR" || fail "no --help"
    echo "describe: ok"
    ;;
  malformed)
    head -c 20 "$data/sony_dualshock4_v2_usb.bin" > "$work/truncated.bin"
    "$bisturi" device describe "$work/truncated.bin" > "$work/truncated.txt" 2>&1
    status=$?
    cat "$work/truncated.txt"
    [ "$status" -eq 2 ] || fail "exit status $status, expected 2"
    grep -q "byte 18: Logical Maximum: item needs 2 data bytes, 1 left" "$work/truncated.txt" ||
      fail "the byte offset and the item are not named"
    echo "malformed: ok"
    ;;
  dump)
    # A short session of the vendor arm's twin, recorded, then dumped: the arm's force commands
    # come out as 3-vectors on its end-effector channel, its reports as decoded poses.
    "$bisturi" run --print-default-scene |
      sed 's/driver = "hid-glove"/driver = "vendor-arm"/' > "$work/arm.toml"
    "$bisturi" run "$work/arm.toml" --duration 0.3 --eye-width 64 --eye-height 64 --no-openxr \
      --out "$work/arm" --record "$work/arm.btrace" > "$work/arm.txt" 2>&1 ||
      { cat "$work/arm.txt"; fail "bisturi run exited $?"; }
    "$bisturi" trace dump "$work/arm.btrace" --device vendor-arm > "$work/dump.txt" ||
      fail "trace dump exited $?"
    grep -q "device 0  force  end_effector=\[[^],]*,[^],]*,[^],]*\] N" "$work/dump.txt" ||
      { head -20 "$work/dump.txt"; fail "no force vector"; }
    grep -q '"end_effector_poses":\[{"orientation_wxyz"' "$work/dump.txt" || fail "no decoded pose"
    grep -q "device 1" "$work/dump.txt" && fail "--device kept another device"
    "$bisturi" trace dump "$work/arm.btrace" --json | grep -q '"trace_error": null' ||
      fail "trace dump --json"
    echo "dump: ok"
    ;;
  *)
    fail "unknown mode $mode"
    ;;
esac
