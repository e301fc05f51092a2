#!/bin/busybox sh
# Guest side of stemd's VM driver tests: runs inside the test VM (tools/vm/run.sh)
# under busybox sh, sets up the real kernel drivers and runs the probes on them.
#
#   guest.sh all KEY=VALUE...        every check (one VM boot for all of them)
#   guest.sh one CHECK KEY=VALUE...  one check (how `all` runs each, under a timeout)
# KEYs: out (results dir, host path), can, v4l2, gpio, libcamera (host paths of
# the probe binaries; empty = not built, the check is skipped).
# For each CHECK it writes OUT/CHECK.log and OUT/CHECK.rc: 0 pass, 77 skipped
# (the log's "SKIP:" line says why), anything else failed. test/vm/check.sh
# turns those into CTest results. Exits 0 when every check has a result.
# Host binaries (probes, can-utils, gpiod tools) run through `hostrun` (chroot
# into the host root); busybox covers the rest.

check_timeout=60

mode=$1
shift
check=
[ "$mode" = one ] && { check=$1; shift; }
out=; can=; v4l2=; gpio=; libcamera=
for kv in "$@"; do
  case $kv in
    out=*) out=${kv#out=} ;;
    can=*) can=${kv#can=} ;;
    v4l2=*) v4l2=${kv#v4l2=} ;;
    gpio=*) gpio=${kv#gpio=} ;;
    libcamera=*) libcamera=${kv#libcamera=} ;;
  esac
done
[ -n "$out" ] || { echo "guest.sh: no out=DIR" >&2; exit 2; }

# Checks print what they do; `die` ends one with a failure, `skip` with 77.
die() { echo "FAILED: $*"; exit 1; }
skip() { echo "SKIP: $*"; exit 77; }
uptime_s() { cut -d' ' -f1 /proc/uptime; }

# --- SocketCAN on vcan0 ------------------------------------------------------
check_can() {
  [ -n "$can" ] || skip "can probe not built"
  modprobe can-raw && modprobe vcan || die "modprobe can-raw vcan"
  ip link add dev vcan0 type vcan && ip link set vcan0 up || die "creating vcan0"

  echo "== probe sends, candump receives"
  frame=1A5#0102030405060708
  hostrun candump -L -n 1 -T 5000 vcan0 > /tmp/candump.out 2>&1 &
  dump=$!
  # candump is ready once its socket is on vcan0's receive list; sending
  # earlier would lose the frame.
  n=0
  until grep -q '^ *vcan0 ' /proc/net/can/rcvlist_all; do
    n=$((n + 1))
    [ $n -le 100 ] || die "candump did not start listening on vcan0"
    sleep 0.05
  done
  hostrun "$can" send vcan0 "$frame" || die "can probe send"
  wait $dump || die "candump exited $? ($(cat /tmp/candump.out))"
  echo "candump: $(cat /tmp/candump.out)"
  grep -q " vcan0 $frame\$" /tmp/candump.out || die "candump did not see $frame"

  echo "== cansend sends, probe receives and decodes"
  hostrun "$can" receive vcan0 0C3#CAFE00F1 3000 -- cansend vcan0 0C3#CAFE00F1 || die "can probe receive"
}

# --- V4L2 on vivid -------------------------------------------------------------
# Finds vivid's node by its name in sysfs (numbering depends on probe order).
v4l_node() {
  for d in /sys/class/video4linux/video*; do
    [ "$(cat "$d/name")" = "$1" ] && { echo "/dev/${d##*/}"; return 0; }
  done
  return 1
}

check_v4l2() {
  [ -n "$v4l2" ] || skip "v4l2 probe not built"
  # One instance with a video capture (0x1) and a video output (0x100) node.
  modprobe vivid n_devs=1 node_types=0x101 || die "modprobe vivid"
  cap=$(v4l_node vivid-000-vid-cap) || die "no vivid capture node"
  outn=$(v4l_node vivid-000-vid-out) || die "no vivid output node"
  hostrun v4l2-ctl --list-devices
  echo "== mmap streaming capture from $cap"
  hostrun "$v4l2" capture "$cap" 10 || die "capture from $cap"
  echo "== known image $outn -> $cap"
  hostrun "$v4l2" loopback "$cap" "$outn" "$out" || die "loopback $outn -> $cap"
}

# --- GPIO on gpio-sim ----------------------------------------------------------
check_gpio() {
  [ -n "$gpio" ] || skip "gpio probe not built: libgpiod-dev (1.x) was missing when CMake configured"
  modprobe gpio-sim || die "modprobe gpio-sim"
  # configfs only once gpio-sim is loaded, or its directory is missing.
  mount -t configfs none /sys/kernel/config || die "mount configfs"
  c=/sys/kernel/config/gpio-sim/stemd
  mkdir "$c" "$c/bank0" || die "gpio-sim configfs"
  echo 4 > "$c/bank0/num_lines"
  for l in 0:valve_out 1:endstop_in 2:spare_in; do
    mkdir "$c/bank0/line${l%%:*}" && echo "${l#*:}" > "$c/bank0/line${l%%:*}/name"
  done
  echo 1 > "$c/live" || die "gpio-sim: going live"
  chip=$(cat "$c/bank0/chip_name")
  sim=/sys/devices/platform/$(cat "$c/dev_name")/$chip
  echo "gpio-sim chip $chip, sysfs $sim"

  echo "== edges on $chip line 1 from gpio-sim pulls"
  # The probe appends "up" or "down" and waits for that edge before the next.
  hostrun "$gpio" events "$chip" 1 3000 -- \
    sh -c 'echo "pull-$2" > "$1"' sh "$sim/sim_gpio1/pull" || die "edge events"

  echo "== output $chip line 0 read back in gpio-sim's sysfs"
  for v in 1 0; do
    hostrun "$gpio" output "$chip" 0 "$v" -- \
      sh -c 'v=$(cat "$1"); echo "gpio-sim: $1 = $v"; [ "$v" = "$2" ]' sh "$sim/sim_gpio0/value" "$v" ||
      die "output line 0 = $v"
  done

  echo "== gpiod tools see a pull (cross-check)"
  echo pull-up > "$sim/sim_gpio2/pull"
  [ "$(hostrun gpioget "$chip" 2)" = 1 ] || die "gpioget $chip 2 after pull-up"
}

# --- libcamera on vimc ---------------------------------------------------------
check_libcamera() {
  [ -n "$libcamera" ] || skip "libcamera probe not built: libcamera-dev was missing when CMake configured"
  modprobe vimc || die "modprobe vimc"
  # libcamera only takes devices udev has "initialized"; there is no udev
  # here, so write that mark into the (tmpfs) udev database for every node.
  for d in /sys/class/video4linux/* /sys/bus/media/devices/* /sys/class/v4l-subdev/*; do
    [ -e "$d/dev" ] && echo "I:1" > "/host/run/udev/data/c$(cat "$d/dev")"
  done
  echo "== list cameras and grab a frame"
  hostrun env LIBCAMERA_LOG_LEVELS='*:ERROR' "$libcamera" vimc || die "libcamera probe"
}

# --- v4l2_source: the project's V4L2 source (drivers/v4l2) on vivid loopback ---
# KEY v4l2_source: host path of stemd-vm-v4l2-source-check.
v4l2_source=
for kv in "$@"; do
  case $kv in v4l2_source=*) v4l2_source=${kv#v4l2_source=} ;; esac
done
check_v4l2_source() {
  [ -n "$v4l2_source" ] || skip "v4l2_source check not built"
  # Same vivid instance as check_v4l2 (a no-op if that check loaded it).
  modprobe vivid n_devs=1 node_types=0x101 || die "modprobe vivid"
  cap=$(v4l_node vivid-000-vid-cap) || die "no vivid capture node"
  outn=$(v4l_node vivid-000-vid-out) || die "no vivid output node"
  for f in yuyv bgr24; do
    echo "== V4l2Source, $f plant scene $outn -> $cap"
    hostrun "$v4l2_source" loop "$cap" "$outn" "$f" "$out" || die "V4l2Source $f loopback"
  done
}
extra_checks="$extra_checks v4l2_source"

# --- socketcan: the project's SocketCAN driver (drivers/socketcan) on vcan0 ---
# KEY socketcan: host path of stemd-vm-socketcan-check. Each step has its own
# timeout (socketcan_timeout), well inside check_timeout.
socketcan=
for kv in "$@"; do
  case $kv in socketcan=*) socketcan=${kv#socketcan=} ;; esac
done
socketcan_timeout=20
check_socketcan() {
  [ -n "$socketcan" ] || skip "socketcan check not built"
  sc() { timeout -s KILL "$socketcan_timeout" hostrun "$socketcan" "$@"; }
  # Precomputed with the protocol encoder (E2E CRC + counter): a change in
  # the encoder or the driver shows up as a mismatch.
  target=301#3223D254400DFFBA    # TARGET id 1234, tool 2, lane 5, fire 200000 mm, -321 mm, weed; counter 3
  odometry=300#3D0706120F0024FA  # ODOMETRY 987654 mm, -1500 mm/s; counter 7
  modprobe can-raw && modprobe vcan || die "modprobe can-raw vcan"
  # check_can may have created vcan0 already.
  ip link show vcan0 > /dev/null 2>&1 || ip link add dev vcan0 type vcan || die "creating vcan0"
  ip link set vcan0 up || die "vcan0 up"

  echo "== the protocol encoder gives the precomputed frames"
  sc frames > /tmp/sc_frames.out 2>&1 || die "socketcan-check frames ($(cat /tmp/sc_frames.out))"
  cat /tmp/sc_frames.out
  grep -qx "target $target" /tmp/sc_frames.out || die "TARGET encodes differently from $target"
  grep -qx "odometry $odometry" /tmp/sc_frames.out || die "ODOMETRY encodes differently from $odometry"

  echo "== SocketCanBus sends an E2E TARGET, candump receives"
  hostrun candump -L -n 1 -T 5000 vcan0 > /tmp/sc_candump.out 2>&1 &
  dump=$!
  n=0
  until grep -q '^ *vcan0 ' /proc/net/can/rcvlist_all; do
    n=$((n + 1))
    [ $n -le 100 ] || die "candump did not start listening on vcan0"
    sleep 0.05
  done
  sc send vcan0 || die "SocketCanBus send"
  wait $dump || die "candump exited $? ($(cat /tmp/sc_candump.out))"
  echo "candump: $(cat /tmp/sc_candump.out)"
  [ "$(wc -l < /tmp/sc_candump.out)" -eq 1 ] || die "candump saw more than one frame"
  grep -q " vcan0 $target\$" /tmp/sc_candump.out || die "candump did not see exactly $target"

  echo "== cansend sends a foreign frame and ODOMETRY; SocketCanBus filters, receives, E2E-checks, decodes"
  sc receive vcan0 3000 -- sh -c 'cansend vcan0 123#00 && cansend vcan0 "$1"' sh "$odometry" ||
    die "SocketCanBus receive"

  echo "== vcan0 down while sending (errors, no crash), then up (sending resumes)"
  sc downup vcan0 -- sh -c 'ip link set "$1" "$2"' sh vcan0 || die "SocketCanBus down/up"
  ip link set vcan0 up
}
extra_checks="$extra_checks socketcan"

# --- libcamera_source: the project's libcamera source (drivers/libcamera) on vimc ---
# KEY libcamera_source: host path of stemd-vm-libcamera-source-check.
libcamera_source=
for kv in "$@"; do
  case $kv in libcamera_source=*) libcamera_source=${kv#libcamera_source=} ;; esac
done
check_libcamera_source() {
  [ -n "$libcamera_source" ] || skip "libcamera_source check not built: libcamera-dev was missing when CMake configured"
  # As check_libcamera (a no-op if that check did it): vimc, and the udev
  # "initialized" mark libcamera needs for every node.
  modprobe vimc || die "modprobe vimc"
  for d in /sys/class/video4linux/* /sys/bus/media/devices/* /sys/class/v4l-subdev/*; do
    [ -e "$d/dev" ] && echo "I:1" > "/host/run/udev/data/c$(cat "$d/dev")"
  done
  echo "== LibcameraSource on vimc: colour bars, timestamps, counters, reopen by id"
  hostrun env LIBCAMERA_LOG_LEVELS='*:ERROR' "$libcamera_source" capture vimc "$out" || die "LibcameraSource on vimc"
}
extra_checks="$extra_checks libcamera_source"

# --- gpiod: the project's GPIO lines (drivers/gpiod) on gpio-sim ---
# KEY gpiod: host path of stemd-vm-gpiod-check. Its own gpio-sim chip
# (configfs "stemd_gpiod": 0 cam_trigger, 1 enable, 2 enc_a, 3 enc_b), so it
# does not depend on check_gpio. The check runs each pull or toggle itself,
# one edge at a time (libgpiod 1.6 reads an edge's level late: see
# tools/vm/README.md). Each step has its own timeout (gpiod_timeout).
gpiod=
for kv in "$@"; do
  case $kv in gpiod=*) gpiod=${kv#gpiod=} ;; esac
done
gpiod_timeout=20
check_gpiod() {
  [ -n "$gpiod" ] || skip "gpiod check not built: libgpiod-dev (1.x) was missing when CMake configured"
  gc() { timeout -s KILL "$gpiod_timeout" hostrun "$gpiod" "$@"; }
  modprobe gpio-sim || die "modprobe gpio-sim"
  # configfs only once gpio-sim is loaded; check_gpio may have mounted it.
  grep -q ' /sys/kernel/config configfs ' /proc/mounts ||
    mount -t configfs none /sys/kernel/config || die "mount configfs"
  c=/sys/kernel/config/gpio-sim/stemd_gpiod
  mkdir "$c" "$c/bank0" || die "gpio-sim configfs"
  echo 4 > "$c/bank0/num_lines"
  # A fixed label: the chip may come back under another number (see "lost").
  echo stemd-gpiod > "$c/bank0/label"
  for l in 0:cam_trigger 1:enable 2:enc_a 3:enc_b; do
    mkdir "$c/bank0/line${l%%:*}" && echo "${l#*:}" > "$c/bank0/line${l%%:*}/name"
  done
  echo 1 > "$c/live" || die "gpio-sim: going live"
  chip=$(cat "$c/bank0/chip_name")
  sim=/sys/devices/platform/$(cat "$c/dev_name")/$chip
  echo "gpio-sim chip $chip, sysfs $sim"

  for al in 0 1; do
    echo "== GpiodLines enable input (active_low=$al) follows gpio-sim pulls on $chip line 1"
    echo pull-down > "$sim/sim_gpio1/pull"
    gc enable chip="$chip" enable=1 active_low=$al -- \
      sh -c 'echo "pull-$2" > "$1"' sh "$sim/sim_gpio1/pull" || die "enable input, active_low=$al"
  done
  echo pull-down > "$sim/sim_gpio1/pull"

  for al in 0 1; do
    echo "== GpiodLines trigger output (active_low=$al) on $chip line 0 read back in gpio-sim's sysfs"
    gc trigger chip="$chip" enable=1 trigger=0 active_low=$al -- \
      sh -c 'v=$(cat "$1"); echo "gpio-sim: $1 = $v (want $2)"; [ "$v" = "$2" ]' sh "$sim/sim_gpio0/value" ||
      die "trigger output, active_low=$al"
  done

  echo "== GpiodLines quadrature encoder on $chip lines 2 (A), 3 (B): 13 edges forward, 5 back"
  echo pull-down > "$sim/sim_gpio2/pull"
  echo pull-down > "$sim/sim_gpio3/pull"
  gc encoder chip="$chip" enable=1 a=2 b=3 n=13 m=5 -- \
    sh -c 'l=2; [ "$2" = b ] && l=3; echo "pull-$3" > "$1/sim_gpio$l/pull"' sh "$sim" || die "quadrature encoder"

  echo "== GpiodLines loses the chip labelled stemd-gpiod (gpio-sim goes away), enable drops, reopens when it is back"
  # By label: gpio-sim comes back as another gpiochipN.
  # The chroot sees configfs only if it is mounted inside /host/sys too.
  grep -q ' /host/sys/kernel/config configfs ' /proc/mounts ||
    mount -t configfs none /host/sys/kernel/config || die "mount configfs in /host/sys"
  gc lost chip=stemd-gpiod enable=1 -- sh -c '
    case $2 in
      up) echo pull-up > "/sys/devices/platform/$(cat "$1/dev_name")/$(cat "$1/bank0/chip_name")/sim_gpio1/pull" ;;
      unplug) echo 0 > "$1/live" ;;
      plug) echo 1 > "$1/live" && echo "gpio-sim back as $(cat "$1/bank0/chip_name")" ;;
    esac' sh "$c" || die "lost chip"
}
extra_checks="$extra_checks gpiod"

# --- libcamera_reopen: LibcameraSource recovers when vimc is unbound and bound again ---
# Same binary as libcamera_source (KEY libcamera_source). Last of the vimc
# checks: it unbinds and rebinds the vimc platform device. The control command
# runs in the chroot (as the check does): rebinding gives new device nodes,
# which need libcamera's udev "initialized" mark again.
check_libcamera_reopen() {
  [ -n "$libcamera_source" ] || skip "libcamera_source check not built: libcamera-dev was missing when CMake configured"
  modprobe vimc || die "modprobe vimc"
  for d in /sys/class/video4linux/* /sys/bus/media/devices/* /sys/class/v4l-subdev/*; do
    [ -e "$d/dev" ] && echo "I:1" > "/host/run/udev/data/c$(cat "$d/dev")"
  done
  [ -e /sys/bus/platform/drivers/vimc/vimc.0 ] || die "vimc.0 is not bound to vimc"
  echo "== LibcameraSource: vimc.0 unbound while streaming (timeouts, backoff), bound again (frames resume)"
  hostrun env LIBCAMERA_LOG_LEVELS='*:ERROR' "$libcamera_source" unplug vimc "$out" -- sh -c '
    case $1 in
      unplug) echo vimc.0 > /sys/bus/platform/drivers/vimc/unbind ;;
      plug)
        echo vimc.0 > /sys/bus/platform/drivers/vimc/bind || exit 1
        for d in /sys/class/video4linux/* /sys/bus/media/devices/* /sys/class/v4l-subdev/*; do
          [ -e "$d/dev" ] && echo "I:1" > "/run/udev/data/c$(cat "$d/dev")"
        done
        echo "vimc.0 bound again: $(ls /sys/bus/media/devices | tr "\n" " ")" ;;
    esac' sh
  rc=$?
  [ $rc -ne 77 ] || skip "libcamera 0.0.3 could not release the unplugged camera this time (see the log above)"
  [ $rc -eq 0 ] || die "LibcameraSource unplug/plug"
}
extra_checks="$extra_checks libcamera_reopen"

# --- paired_nir: PairedNirSource (drivers/v4l2/paired_nir_source) on two vivid instances ---
# KEY paired_nir: host path of stemd-vm-paired-nir-check. Instance 000 loops the
# RGB scene (BGR24), instance 001 the NIR scene (GREY); each has its own
# output -> capture loopback. After the other vivid checks: it reloads vivid
# with two instances (they loaded one).
paired_nir=
for kv in "$@"; do
  case $kv in paired_nir=*) paired_nir=${kv#paired_nir=} ;; esac
done
check_paired_nir() {
  [ -n "$paired_nir" ] || skip "paired_nir check not built"
  if grep -q '^vivid ' /proc/modules; then rmmod vivid || die "rmmod vivid"; fi
  modprobe vivid n_devs=2 node_types=0x101,0x101 || die "modprobe vivid n_devs=2"
  rgb_cap=$(v4l_node vivid-000-vid-cap) || die "no vivid-000 capture node"
  rgb_out=$(v4l_node vivid-000-vid-out) || die "no vivid-000 output node"
  nir_cap=$(v4l_node vivid-001-vid-cap) || die "no vivid-001 capture node"
  nir_out=$(v4l_node vivid-001-vid-out) || die "no vivid-001 output node"
  echo "== PairedNirSource: RGB $rgb_out -> $rgb_cap, NIR $nir_out -> $nir_cap"
  hostrun "$paired_nir" loop "$rgb_cap" "$rgb_out" "$nir_cap" "$nir_out" "$out" || die "PairedNirSource on two vivid loopbacks"
}
extra_checks="$extra_checks paired_nir"

# --- daemon: the real stemd binary on vivid, vcan0 and gpio-sim ---
# KEYs daemon (stemd-vm-daemon-check: feeds frames, judges the bus) and stemd
# (the daemon). stemd captures from vivid-000's capture node, which the check
# feeds through the loopback with a field scrolling past at the configured
# speed; sends on vcan0 (candump -L records it); its enable input is line 0
# of its own gpio-sim chip. The check pulls that line down between the two
# groups of plants. Last: it takes vivid as the checks before left it.
daemon=; stemd=
for kv in "$@"; do
  case $kv in
    daemon=*) daemon=${kv#daemon=} ;;
    stemd=*) stemd=${kv#stemd=} ;;
  esac
done
# wait_until N CMD...: runs CMD every 50 ms until it succeeds (0) or N tries failed (1).
wait_until() {
  n=$1
  shift
  until "$@"; do
    n=$((n - 1))
    [ $n -gt 0 ] || return 1
    sleep 0.05
  done
}
check_daemon() {
  [ -n "$daemon" ] && [ -n "$stemd" ] || skip "daemon check not built: libgpiod-dev (1.x) was missing when CMake configured"
  grep -q '^vivid ' /proc/modules || modprobe vivid n_devs=1 node_types=0x101 || die "modprobe vivid"
  cap=$(v4l_node vivid-000-vid-cap) || die "no vivid capture node"
  outn=$(v4l_node vivid-000-vid-out) || die "no vivid output node"
  modprobe can-raw && modprobe vcan || die "modprobe can-raw vcan"
  ip link show vcan0 > /dev/null 2>&1 || ip link add dev vcan0 type vcan || die "creating vcan0"
  ip link set vcan0 up || die "vcan0 up"
  modprobe gpio-sim || die "modprobe gpio-sim"
  grep -q ' /sys/kernel/config configfs ' /proc/mounts ||
    mount -t configfs none /sys/kernel/config || die "mount configfs"
  c=/sys/kernel/config/gpio-sim/stemd_daemon
  mkdir "$c" "$c/bank0" "$c/bank0/line0" || die "gpio-sim configfs"
  echo 2 > "$c/bank0/num_lines"
  echo enable > "$c/bank0/line0/name"
  echo 1 > "$c/live" || die "gpio-sim: going live"
  chip=$(cat "$c/bank0/chip_name")
  pull=/sys/devices/platform/$(cat "$c/dev_name")/$chip/sim_gpio0/pull
  echo pull-up > "$pull" || die "pull-up enable"
  echo "vivid $outn -> $cap, vcan0, gpio-sim $chip line 0 (enable) pulled up"

  t0=$(uptime_s)
  hostrun "$daemon" feed "$cap" "$outn" -- sh -c 'echo "pull-$2" > "$1"' sh "$pull" > /tmp/feeder.log 2>&1 &
  feeder=$!
  wait_until 200 grep -q '^ready' /tmp/feeder.log || die "feeder did not get ready: $(cat /tmp/feeder.log)"
  echo "t=$(uptime_s) s: $(cat /tmp/feeder.log)"
  hostrun candump -L vcan0 > /tmp/daemon.candump 2> /tmp/candump.err &
  dump=$!
  # As check_can: candump is ready once its socket is on vcan0's receive list.
  wait_until 100 grep -q '^ *vcan0 ' /proc/net/can/rcvlist_all || die "candump did not start listening on vcan0"
  sets=
  for s in $(hostrun "$daemon" config) source.v4l2_device="$cap" can.interface=vcan0 gpio.chip="$chip" gpio.enable_line=0; do
    sets="$sets --set $s"
  done
  echo "== t=$(uptime_s) s: stemd$sets --map $out/daemon-map.jsonl"
  # shellcheck disable=SC2086  # one word per setting
  hostrun "$stemd" $sets --map "$out/daemon-map.jsonl" > /tmp/stemd.log 2>&1 &
  daemon_pid=$!
  # Active once it has frames (HEARTBEAT byte 1: state << 4 | counter).
  n=0
  until grep -q ' vcan0 303#..[23]' /tmp/daemon.candump; do
    n=$((n + 1))
    if [ $n -gt 500 ] || ! kill -0 $daemon_pid 2>/dev/null; then
      cat /tmp/stemd.log; kill $feeder $dump 2>/dev/null; die "stemd did not become active"
    fi
    sleep 0.05
  done
  echo "t=$(uptime_s) s: stemd active; feeding the field"
  kill -USR1 $feeder
  n=0
  until grep -q '^done' /tmp/feeder.log; do
    n=$((n + 1))
    if [ $n -gt 600 ] || ! kill -0 $feeder 2>/dev/null; then
      cat /tmp/feeder.log /tmp/stemd.log; kill $daemon_pid $dump 2>/dev/null; die "feeder did not finish"
    fi
    sleep 0.05
  done
  sleep 1  # the last plants' outcomes reach a heartbeat
  echo "== SIGTERM stemd"
  ts=$(uptime_s)
  kill -TERM $daemon_pid
  n=0
  while kill -0 $daemon_pid 2>/dev/null; do
    n=$((n + 1))
    [ $n -le 40 ] || break
    sleep 0.025
  done
  te=$(uptime_s)
  alive=0; kill -0 $daemon_pid 2>/dev/null && alive=1
  [ $alive = 0 ] || kill -KILL $daemon_pid
  wait $daemon_pid
  rc=$?
  kill -TERM $feeder; wait $feeder; frc=$?
  kill -INT $dump; wait $dump
  echo "--- stemd log"; cat /tmp/stemd.log; echo "---"
  cat /tmp/feeder.log
  rm -f "/host$out/daemon.candump"
  cp /tmp/daemon.candump "/host$out/daemon.candump"
  echo "stemd exited $rc $(echo "$te $ts" | awk '{printf "%.3f", $1 - $2}') s after SIGTERM; feed took $(echo "$(uptime_s) $t0" | awk '{printf "%.1f", $1 - $2}') s in all"
  [ $alive = 0 ] || die "stemd still running 1 s after SIGTERM"
  [ $rc = 0 ] || die "stemd exited $rc on SIGTERM"
  [ $frc = 0 ] || die "feeder exited $frc"
  echo "== the bus: $(wc -l < /tmp/daemon.candump) frames"
  hostrun "$daemon" verify "$out/daemon.candump" "$out/daemon-map.jsonl" || die "the daemon's CAN frames"
}
extra_checks="$extra_checks daemon"

# --- toolsim: stemd-toolsim (the simulated tool controller) on vcan0 ---
# KEY toolsim: host path of stemd-toolsim. It drives at 1400 mm/s from
# odometer 0 (sending ODOMETRY) and fires with a 40 ms delay; cansend gives it
# one TARGET (precomputed with the protocol encoder: tool 2, target 1234,
# lane 5, fire_odom_mm 7000, weed; counter 0: 5 s of driving, room for a
# slow emulated guest to send it in time). The strike must land 56 mm
# (1.4 m/s x 40 ms) past it, reported on stdout and as TOOL_FIRED (base+4).
toolsim=
for kv in "$@"; do
  case $kv in toolsim=*) toolsim=${kv#toolsim=} ;; esac
done
check_toolsim() {
  [ -n "$toolsim" ] || skip "stemd-toolsim not built"
  target=301#A820D254581B0080
  modprobe can-raw && modprobe vcan || die "modprobe can-raw vcan"
  ip link show vcan0 > /dev/null 2>&1 || ip link add dev vcan0 type vcan || die "creating vcan0"
  ip link set vcan0 up || die "vcan0 up"
  hostrun candump -L vcan0 > /tmp/toolsim.candump 2> /tmp/toolsim.candump.err &
  dump=$!
  wait_until 100 grep -q '^ *vcan0 ' /proc/net/can/rcvlist_all || die "candump did not start listening on vcan0"
  hostrun "$toolsim" --interface vcan0 --delay-ms 40 --speed-mm-per-s 1400 --duration-s 8 > /tmp/toolsim.out 2>&1 &
  sim=$!
  # It listens once it drives (its first ODOMETRY, 300#, is on the bus).
  wait_until 100 grep -q ' vcan0 300#' /tmp/toolsim.candump || { kill $sim $dump; die "no ODOMETRY from stemd-toolsim"; }
  hostrun cansend vcan0 "$target" || die "cansend $target"
  wait $sim
  rc=$?
  kill -INT $dump; wait $dump
  cat /tmp/toolsim.out
  echo "candump: $(grep -c ' vcan0 304#' /tmp/toolsim.candump) TOOL_FIRED frames, $(wc -l < /tmp/toolsim.candump) in all"
  [ $rc = 0 ] || die "stemd-toolsim exited $rc"
  grep -qx 'fired tool 2 target 1234 lane 5 fired_odom_mm 7056' /tmp/toolsim.out || die "the strike was not at 7056 mm"
  [ "$(grep -c ' vcan0 304#' /tmp/toolsim.candump)" -eq 1 ] || die "not exactly one TOOL_FIRED on vcan0"
}
extra_checks="$extra_checks toolsim"

if [ "$mode" = one ]; then
  "check_$check"
  exit $?
fi

status=0
for c in can v4l2 gpio libcamera $extra_checks; do
  t0=$(uptime_s)
  timeout -s KILL "$check_timeout" sh "$0" one "$c" "$@" > "/host$out/$c.log" 2>&1
  rc=$?
  [ $rc -ne 137 ] || echo "FAILED: timed out after ${check_timeout}s" >> "/host$out/$c.log"
  echo "$rc" > "/host$out/$c.rc" || status=1
  echo "check $c: rc=$rc (t=$t0..$(uptime_s) s)"
done
exit $status
