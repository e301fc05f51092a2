#!/usr/bin/env bash
# Prepares the test VM that runs stemd's driver tests against REAL kernel drivers
# (vcan, vivid, gpio-sim, vimc): this machine's kernel has none of them and cannot
# load modules, so we boot Debian's own 6.1 kernel under QEMU (TCG) instead.
#
#   tools/vm/prepare.sh CACHE_DIR
#
# CACHE_DIR (in the build tree, never in git) ends up holding:
#   vmlinux          uncompressed kernel (QEMU boots it through PVH; saves the
#                    ~2.5 s of xz decompression that TCG would emulate)
#   initramfs.cpio   busybox + the modules the tests need + tools/vm/init
#   stamp            "kernel=<version> initramfs=<hash>" of what is built
# Idempotent: when the stamp matches, it returns in well under a second without
# network. The heavy part (kernel download, out-of-tree module build) is redone
# only when apt's current kernel version changes; the initramfs is repacked when
# tools/vm/init or this script changes.
# Needs root (or sudo) only when packages are missing.
set -euo pipefail
export PATH=$PATH:/usr/sbin:/sbin
here=$(cd "$(dirname "$0")" && pwd)

[ $# -eq 1 ] || { echo "usage: $0 CACHE_DIR" >&2; exit 2; }
mkdir -p "$1"
cache=$(cd "$1" && pwd)
log() { printf 'vm-prepare: %s\n' "$*" >&2; }
trap 'log "FAILED (line $LINENO: $BASH_COMMAND)"' ERR

# Host packages. The guest runs host binaries (can-utils, gpiod tools, the
# probes and their libraries) through a chroot into the host root, so those are
# installed on the host; kernel, busybox and kernel source are only downloaded.
host_packages=(qemu-system-x86 kmod cpio xz-utils gcc make can-utils v4l-utils gpiod
               libcamera-ipa)

sudo=()
[ "$(id -u)" -eq 0 ] || sudo=(sudo)
apt_updated=0
apt_update() {
  [ "$apt_updated" = 1 ] && return
  log "apt-get update"
  "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get update -q >&2
  apt_updated=1
}
installed() { dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q "install ok installed"; }

# The kernel ABI version apt currently offers (e.g. 6.1.0-56-amd64). Never
# hard-coded: the archive keeps only the newest 6.1 build, and out-of-tree
# modules load only on the exact kernel they were built for.
current_kernel() {
  apt-cache depends linux-image-amd64 2>/dev/null |
    sed -n 's/^ *Depends: linux-image-\(6\.1\.[0-9]*-[0-9]*-amd64\)$/\1/p; T; q'
}

# The initramfs content hash: repack when the guest's init or the packing changes.
initramfs_hash() { cat "$here/init" "$here/prepare.sh" | sha256sum | cut -c1-16; }

# Sets kv, want and missing from apt's (local) package lists.
assess() {
  kv=$(current_kernel)
  want="kernel=$kv initramfs=$(initramfs_hash)"
  missing=()
  local p
  for p in "${host_packages[@]}" "linux-headers-$kv"; do installed "$p" || missing+=("$p"); done
}
assess
[ -n "$kv" ] || { apt_update; assess; }
[ -n "$kv" ] || { log "apt offers no linux-image-6.1.*-amd64 (linux-image-amd64 has no 6.1 dependency)"; exit 1; }

if [ ${#missing[@]} -eq 0 ] && [ "$(cat "$cache/stamp" 2>/dev/null)" = "$want" ] &&
   [ -s "$cache/vmlinux" ] && [ -s "$cache/initramfs.cpio" ]; then
  log "up to date ($want)"
  exit 0
fi

if [ ${#missing[@]} -gt 0 ]; then
  # Fresh lists may name a newer kernel: install (and build) for that one.
  apt_update
  assess
fi
if [ ${#missing[@]} -gt 0 ]; then
  log "installing ${missing[*]}"
  "${sudo[@]}" env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "${missing[@]}" >&2
fi

old_stamp=$(cat "$cache/stamp" 2>/dev/null || true)
old_kv=$(echo "$old_stamp" | sed -n 's/^kernel=\([^ ]*\).*/\1/p')
if [ "$old_stamp" = "$want" ] && [ -s "$cache/vmlinux" ] && [ -s "$cache/initramfs.cpio" ]; then
  log "ready ($want), ${SECONDS} s"
  exit 0
fi
rm -f "$cache/stamp"   # a half-done preparation must not look done
kdir=$cache/kernel/$kv
if [ "$old_kv" != "$kv" ] || [ ! -e "$kdir/done" ] || [ ! -s "$cache/vmlinux" ]; then
  log "building kernel pieces for $kv (was: ${old_kv:-none})"
  rm -rf "$cache/kernel" "$cache/debs" "$cache/vmlinux"
  mkdir -p "$kdir" "$cache/debs"
  # The linux-source version that matches the image package exactly, so the
  # out-of-tree modules are built from the same source as the kernel.
  image_ver=$(apt-cache policy "linux-image-$kv" | sed -n 's/^ *Candidate: //p')
  (cd "$cache/debs" &&
   apt-get download -q "linux-image-$kv" busybox-static >&2 &&
   { apt-get download -q "linux-source-6.1=$image_ver" >&2 ||
     { log "linux-source-6.1=$image_ver not available, taking apt's candidate"; apt-get download -q linux-source-6.1 >&2; }; })
  dpkg-deb -x "$cache"/debs/linux-image-"$kv"_*.deb "$kdir/image"
  dpkg-deb -x "$cache"/debs/busybox-static_*.deb "$kdir/busybox"

  # vmlinuz is a bzImage whose payload is one xz stream: find its magic and unpack.
  vmlinuz=$kdir/image/boot/vmlinuz-$kv
  off=$(export LC_ALL=C; grep -obUaP -m1 '\xfd7zXZ\x00' "$vmlinuz" | cut -d: -f1 | sed -n 1p)
  [ -n "$off" ] || { log "no xz payload in $vmlinuz"; exit 1; }
  # Through a file: xz stops reading at the stream's end, a pipe would SIGPIPE tail.
  tail -c +"$((off + 1))" "$vmlinuz" > "$cache/vmlinux.xz"
  xz -dc --single-stream "$cache/vmlinux.xz" > "$cache/vmlinux.tmp"
  rm "$cache/vmlinux.xz"
  mv "$cache/vmlinux.tmp" "$cache/vmlinux"

  # Debian's kernel leaves out GPIO_SIM, IRQ_SIM (which gpio-sim needs) and
  # VIDEO_VIMC: build them out of tree from the matching source.
  oot=$kdir/oot
  mkdir -p "$oot" "$kdir/src"
  dpkg-deb --fsys-tarfile "$cache"/debs/linux-source-6.1_*.deb |
    tar -xO ./usr/src/linux-source-6.1.tar.xz |
    tar -xJ -C "$kdir/src" --strip-components=1 \
      linux-source-6.1/drivers/gpio/gpio-sim.c linux-source-6.1/drivers/gpio/gpiolib.h \
      linux-source-6.1/kernel/irq/irq_sim.c --wildcards 'linux-source-6.1/drivers/media/test-drivers/vimc/*'
  cp "$kdir"/src/drivers/gpio/{gpio-sim.c,gpiolib.h} "$kdir/src/kernel/irq/irq_sim.c" \
     "$kdir"/src/drivers/media/test-drivers/vimc/*.[ch] "$oot/"
  # irq_sim is normally built in: as a module it needs a licence, and
  # irq_to_desc() is not exported in 6.1 (generic_handle_irq() does the same here).
  sed -i 's/handle_simple_irq(irq_to_desc(irqnum));/generic_handle_irq(irqnum);/; 1a #include <linux/module.h>' \
    "$oot/irq_sim.c"
  grep -q 'generic_handle_irq(irqnum);' "$oot/irq_sim.c" || { log "irq_sim.c patch did not apply"; exit 1; }
  echo 'MODULE_LICENSE("GPL");' >> "$oot/irq_sim.c"
  printf '%s\n' 'obj-m := irq_sim.o gpio-sim.o vimc.o' \
    'vimc-y := vimc-core.o vimc-common.o vimc-streamer.o vimc-capture.o vimc-debayer.o vimc-scaler.o vimc-sensor.o vimc-lens.o' \
    > "$oot/Kbuild"
  log "building irq_sim, gpio-sim, vimc against /lib/modules/$kv/build"
  make -s -C "/lib/modules/$kv/build" M="$oot" -j"$(nproc)" modules >&2
  rm -rf "$kdir/src" "$cache/debs"   # 200 MB of packages, all unpacked by now
  touch "$kdir/done"
fi

# initramfs: busybox, the modules the tests load (with their dependencies, as
# modprobe resolves them over the distro tree plus our out-of-tree ones), /init.
log "packing initramfs"
work=$cache/initramfs.work
rm -rf "$work"
full=$work/full/lib/modules/$kv
mkdir -p "$full"
cp -al "$kdir/image/lib/modules/$kv/." "$full/"
mkdir -p "$full/extra"
for k in "$kdir"/oot/*.ko; do strip --strip-debug -o "$full/extra/$(basename "$k")" "$k"; done
depmod -b "$work/full" "$kv"
root=$work/root
mkdir -p "$root"/{bin,sbin,dev,proc,sys,tmp,host} "$root/lib/modules/$kv"
cp "$kdir/busybox/bin/busybox" "$root/bin/busybox"
modules=(vcan can-raw sch_tbf vivid configfs gpio-sim vimc virtio_pci 9pnet_virtio 9p)
for m in "${modules[@]}"; do
  modprobe -d "$work/full" -S "$kv" --show-depends "$m" | awk '$1 == "insmod" { print $2 }'
done | sort -u | while read -r ko; do
  rel=${ko#"$full"/}
  mkdir -p "$root/lib/modules/$kv/$(dirname "$rel")"
  cp "$ko" "$root/lib/modules/$kv/$rel"
done
cp "$kdir/image/lib/modules/$kv"/modules.{builtin,builtin.modinfo,order} "$root/lib/modules/$kv/"
depmod -b "$root" "$kv"
install -m 755 "$here/init" "$root/init"
(cd "$root" && find . | cpio -o -H newc --quiet) > "$cache/initramfs.cpio.tmp"
mv "$cache/initramfs.cpio.tmp" "$cache/initramfs.cpio"
rm -rf "$work"

echo "$want" > "$cache/stamp"
log "ready: $want, initramfs $(du -h "$cache/initramfs.cpio" | cut -f1), ${SECONDS} s"
