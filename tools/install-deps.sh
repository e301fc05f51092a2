#!/usr/bin/env bash
# Installs the Debian 12 packages stemd builds and tests with. Idempotent:
# when everything is already installed it does nothing (no network).
set -euo pipefail

packages=(
  g++ cmake ninja-build pkg-config
  libopencv-dev libspdlog-dev
  libyaml-cpp-dev  # the config file reader (src/config/config.cpp), ROS camera_info files
  libcli11-dev nlohmann-json3-dev  # the tools' arguments (stemd-toolsim's too) and JSON output (header-only)
  libgtest-dev libgmock-dev libbenchmark-dev
  libgpiod-dev libcamera-dev  # APIs the VM driver probes (test/vm) build against
  can-utils python3-canmatrix  # third-party readers of our candump logs and DBC (cross-check tests)
  clang libclang-rt-14-dev  # the libFuzzer build of the parsers (test/fuzz)
  systemd python3  # systemd-analyze verify of the unit; a stand-in notify socket in a daemon test
  iproute2  # lo in the private network namespace of the unanswered-DNS test (test/daemon/gpsd_dns.sh)
  libgps-dev nlohmann-json3-dev  # the gpsd client (drivers/gpsd); JSON: the GeoJSON plant map, the live view
  gpsd gpsd-clients gdal-bin  # gpsfake and ogrinfo for the georeferenced map's test (test/daemon/gnss_gpsfake.py)
  libcpp-httplib-dev  # the live view's HTTP server (src/web)
  chromium python3-prometheus-client python3-pil  # the live view's tests: headless browser, /metrics parser, screenshot
  python3-opencv python3-numpy python3-yaml  # measurement scripts on real frames (tools/iou-ceiling.py, outline-rules.py, eval-classes.py)
)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi

sudo=()
[ "$(id -u)" -eq 0 ] || sudo=(sudo)
echo "install-deps: installing ${missing[*]}"
# env, not export: sudo would drop an exported DEBIAN_FRONTEND.
"${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -q
"${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "${missing[@]}"
