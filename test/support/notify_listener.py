"""A stand-in for systemd's notify socket: notify_listener.py SOCKET OUT TIMEOUT_S [stamp].

Binds the datagram socket SOCKET, touches SOCKET.ready, and writes each
message on one line of OUT (newlines folded to spaces; prefixed by
time.monotonic() with `stamp`) until STOPPING=1 or TIMEOUT_S of silence.
"""
import socket
import sys
import time

path, out_path, timeout_s = sys.argv[1], sys.argv[2], float(sys.argv[3])
stamp = len(sys.argv) > 4 and sys.argv[4] == "stamp"
s = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
s.bind(path)
s.settimeout(timeout_s)
with open(out_path, "w", buffering=1) as out:
    open(path + ".ready", "w").close()
    while True:
        try:
            msg = s.recv(4096).decode()
        except socket.timeout:
            break
        line = msg.replace("\n", " ")
        out.write(("%.3f %s\n" % (time.monotonic(), line)) if stamp else line + "\n")
        if msg == "STOPPING=1":
            break
