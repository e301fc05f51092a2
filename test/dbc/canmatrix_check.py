#!/usr/bin/python3
"""Decodes the C++ encoder's frames with canmatrix (Debian: python3-canmatrix)
through the committed DBC and compares every signal with the value encoded.

usage: canmatrix_check.py DBC FRAMES_PROGRAM
FRAMES_PROGRAM prints the frames (see encoded_frames.cpp). Exit 0 if all
agree, 1 if not, 77 (a skip) if canmatrix is not installed.
"""
import logging
import subprocess
import sys

SKIP = 77

try:
    logging.disable(logging.CRITICAL)  # canmatrix logs its optional formats
    import canmatrix
    import canmatrix.formats
except ImportError as e:
    print("SKIP: canmatrix is not installed (Debian: apt-get install python3-canmatrix): %s" % e)
    sys.exit(SKIP)


def crc8_sae_j1850(data):
    """Poly 0x1D, init 0xFF, xor-out 0xFF, bit by bit: apart from the C++ table."""
    crc = 0xFF
    for byte in data:
        crc ^= byte
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1D) & 0xFF if crc & 0x80 else (crc << 1) & 0xFF
    return crc ^ 0xFF


def parse_candump(text):
    """'(1.000000) can0 301#0102' -> (0x301, bytes)."""
    ident, _, data = text.partition("#")
    return int(ident, 16), bytes.fromhex(data)


def main(dbc_path, frames_program):
    db = canmatrix.formats.loadp_flat(dbc_path)
    if db is None:
        return "canmatrix cannot read %s" % dbc_path
    lines = subprocess.run([frames_program], check=True, capture_output=True, text=True).stdout.splitlines()
    errors = []
    seen = {}  # message name -> frames checked
    for line in lines:
        stamp, interface, frame_text, name, *fields = line.split()
        ident, data = parse_candump(frame_text)
        frame = db.frame_by_id(canmatrix.ArbitrationId(ident, extended=False))
        where = "%s (%s)" % (frame_text, name)
        if frame is None or frame.name != name:
            errors.append("%s: the DBC has %s for 0x%03X" % (where, frame.name if frame else "nothing", ident))
            continue
        if frame.size != len(data):
            errors.append("%s: DLC %d, the DBC says %d" % (where, len(data), frame.size))
            continue
        want = {"e2e_crc": (crc8_sae_j1850(bytes([ident & 0xFF, ident >> 8]) + data[1:]), None)}
        for f in fields:
            key, _, value = f.partition("=")
            number, _, label = value.partition(":")
            want[key] = (int(number), label or None)
        decoded = frame.decode(data)
        if set(decoded) != set(want):
            errors.append("%s: the DBC's signals %s, the encoder's %s" % (where, sorted(decoded), sorted(want)))
            continue
        for key, (value, label) in want.items():
            got = decoded[key]
            signal = got.signal
            if got.phys_value != value:
                errors.append("%s: %s reads %s, encoded %d" % (where, key, got.phys_value, value))
            if not signal.min <= got.phys_value <= signal.max:
                errors.append("%s: %s = %s outside the DBC's [%s, %s]" % (where, key, got.phys_value, signal.min, signal.max))
            if label is not None and got.named_value != label:
                errors.append("%s: %s is named %r, expected %r" % (where, key, got.named_value, label))
            if label is None and int(got.phys_value) in signal.values:
                errors.append("%s: %s = %d has a name in the DBC (%r), the protocol gives none"
                              % (where, key, value, signal.values[int(got.phys_value)]))
        seen[name] = seen.get(name, 0) + 1

    # Every message of the DBC got enough frames for its alive counter (0..14)
    # to wrap, and each carries its descriptions.
    for frame in db.frames:
        if seen.get(frame.name, 0) < 16:
            errors.append("%s: only %d frames checked" % (frame.name, seen.get(frame.name, 0)))
        if not frame.comment:
            errors.append("%s: no comment" % frame.name)
        for signal in frame.signals:
            if not signal.comment:
                errors.append("%s.%s: no comment" % (frame.name, signal.name))

    for e in errors[:20]:
        print(e)
    if errors:
        return "%d mismatches (first 20 above) in %d frames" % (len(errors), len(lines))
    print("%d frames of %d messages decode to the values encoded" % (sum(seen.values()), len(seen)))
    return None


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    sys.exit(main(sys.argv[1], sys.argv[2]))
