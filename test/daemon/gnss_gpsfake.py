#!/usr/bin/env python3
"""The georeferenced plant map end to end (README, "Georeferenced plant map").

1. Without gpsd: stemd runs, logs gpsd's host:port and errno, and every
   plant in the map says georef "no_fix" with null coordinates.
2. With gpsfake: stemd replays a generated strip (a constant-speed odometer)
   while gpsfake feeds a private gpsd a straight RTK track (GGA+RMC+GST at
   10 Hz, with checksums), generated once stemd has said when its odometer
   started, so that the track's distance equals the odometer at every
   instant (the fixes carry their UTC time; gnss.time gnss maps it onto
   CLOCK_MONOTONIC). gpsfake feeds faster than real time (a watcher
   client tells when it is through); the replay loops until enough plants
   have ended after that; nothing waits on a guessed delay, every wait
   polls a file, a socket or a process.
   Each plant's latitude/longitude must lie within 20 mm plus the log's
   GNSS error of the truth: the track at the plant's s_mm, plus the
   machine-frame offset from the antenna to (camera.x_mm, y_mm) rotated by
   the track's heading. The GeoJSON is read back with Python's json (and
   GDAL's ogrinfo when installed), once while stemd runs (its 30 s
   rewrite) and once after it exits.
usage: gnss_gpsfake.py STEMD TOOLS_DIR SOURCE_DIR
"""
import calendar
import datetime
import json
import math
import os
import re
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import gnss_nmea  # noqa: E402

SKIP = 77
SPEED_MM_PER_S = 2000 / 3.6     # the strip's 2 km/h
CAMERA_X_MM = 400.0
ANTENNA_X_MM = -850.0
ANTENNA_Y_MM = 250.0
TRACK = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data", "bonirob_leica_gps.txt")
MIN_PLANTS_AFTER_FEED = 12
HEADING_BASELINE_MM = 2000      # gnss.heading_baseline_mm (the default)
WAIT_S = 240


def fail(msg):
    print("FAIL: " + msg, file=sys.stderr)
    sys.exit(1)


def wait_for(what, predicate, timeout_s=WAIT_S, procs=()):
    """Polls predicate() until it is true; fails after timeout_s or when a
    process it needs has exited."""
    deadline = time.monotonic() + timeout_s
    while True:
        v = predicate()
        if v:
            return v
        for name, p, log in procs:
            if p.poll() is not None:
                fail("%s exited %s while waiting for %s: %s" % (name, p.returncode, what, tail(log)))
        if time.monotonic() > deadline:
            fail("no %s within %d s" % (what, timeout_s))
        time.sleep(0.05)


def tail(path, n=15):
    try:
        with open(path, errors="replace") as f:
            return "".join(f.readlines()[-n:])
    except OSError:
        return "(no log)"


def bonirob_track():
    """The Leica track in a tangent plane at its first fix, against its
    least-squares line: direction u (of travel), each fix's distance along
    it from the first (d) and its deviation to the left (c, the log's
    GNSS error as far as this test can tell), the tile length."""
    rows = [l.split() for l in open(TRACK) if not l.startswith("#")]
    t = [float(r[0]) for r in rows]
    origin = (float(rows[0][1]), float(rows[0][2]), float(rows[0][3]))
    enu = gnss_nmea.Enu(*origin)
    pts = [enu.to_enu(float(r[1]), float(r[2]), float(r[3])) for r in rows]
    n = len(pts)
    me, mn = sum(p[0] for p in pts) / n, sum(p[1] for p in pts) / n
    sxx = sum((p[0] - me) ** 2 for p in pts)
    syy = sum((p[1] - mn) ** 2 for p in pts)
    sxy = sum((p[0] - me) * (p[1] - mn) for p in pts)
    th = 0.5 * math.atan2(2 * sxy, sxx - syy)
    ux, uy = math.cos(th), math.sin(th)
    if (pts[-1][0] - pts[0][0]) * ux + (pts[-1][1] - pts[0][1]) * uy < 0:
        ux, uy = -ux, -uy
    along = [(p[0] - me) * ux + (p[1] - mn) * uy for p in pts]
    c = [-(p[0] - me) * uy + (p[1] - mn) * ux for p in pts]
    d = [a - along[0] for a in along]
    if any(d[i + 1] <= d[i] for i in range(n - 1)):
        fail("the BoniRob track does not advance along its line at every fix")
    # The line through the first fix's projection is the plane's origin.
    e0, n0 = me + along[0] * ux, mn + along[0] * uy
    lat0, lon0, h0 = enu.to_geodetic(e0, n0, 0)
    return {"origin": (lat0, lon0, h0), "u": (ux, uy), "d": d, "c": c, "length": d[-1] + d[-1] / (n - 1),
            "course": 90 - math.degrees(math.atan2(uy, ux)), "rms": math.sqrt(sum(x * x for x in c) / n),
            "max_c": max(abs(x) for x in c)}


class GpsdWatcher:
    """A second gpsd client on a non-blocking socket: the UTC times of
    the first and the newest position reports it has seen."""

    def __init__(self, port):
        self.sock = socket.create_connection(("127.0.0.1", port), timeout=10)
        self.sock.sendall(b'?WATCH={"enable":true,"json":true};\n')
        self.sock.setblocking(False)
        self.buf = b""
        self.first_ns = 0
        self.last_ns = 0

    def poll(self):
        try:
            while True:
                data = self.sock.recv(65536)
                if not data:
                    break
                self.buf += data
        except BlockingIOError:
            pass
        *lines, self.buf = self.buf.split(b"\n")
        for line in lines:
            report = json.loads(line)
            if report.get("class") == "TPV" and "time" in report and report.get("mode", 0) >= 2:
                t = datetime.datetime.strptime(report["time"], "%Y-%m-%dT%H:%M:%S.%fZ")
                t_ns = calendar.timegm(t.timetuple()) * 1_000_000_000 + t.microsecond * 1000
                self.first_ns = self.first_ns or t_ns
                self.last_ns = max(self.last_ns, t_ns)
        return True

    def close(self):
        self.sock.close()


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def map_lines(path):
    try:
        with open(path) as f:
            text = f.read()
    except FileNotFoundError:
        return []
    return [json.loads(line) for line in text.split("\n")[:-1] if line]


def clock_offset_ns():
    """CLOCK_REALTIME - CLOCK_MONOTONIC, the narrowest of a few readings."""
    best = None
    for _ in range(20):
        m0 = time.clock_gettime_ns(time.CLOCK_MONOTONIC)
        r = time.clock_gettime_ns(time.CLOCK_REALTIME)
        m1 = time.clock_gettime_ns(time.CLOCK_MONOTONIC)
        if best is None or m1 - m0 < best[0]:
            best = (m1 - m0, r - (m0 + m1) // 2)
    return best[1]


def stemd_args(stemd, src, rec, tmp, port, extra):
    return [stemd, "--config", os.path.join(src, "config/stemd.yaml"), "--replay", rec,
            "--set", "odometry.source=constant", "--set", "odometry.speed_mm_per_s=%.4f" % SPEED_MM_PER_S,
            "--set", "scheduler.policy=all", "--set", "camera.x_mm=%g" % CAMERA_X_MM,
            "--set", "gnss.source=gpsd", "--set", "gnss.host=127.0.0.1", "--set", "gnss.port=%d" % port,
            "--set", "gnss.antenna_x_mm=%g" % ANTENNA_X_MM, "--set", "gnss.antenna_y_mm=%g" % ANTENNA_Y_MM,
            "--can-log", os.path.join(tmp, "can.log")] + extra


def without_gpsd(stemd, src, rec, tmp):
    port = free_port()   # nothing listens there
    m = os.path.join(tmp, "nofix.jsonl")
    g = os.path.join(tmp, "nofix.geojson")
    err = os.path.join(tmp, "nofix.err")
    with open(err, "w") as e:
        rc = subprocess.run(stemd_args(stemd, src, rec, tmp, port,
                                       ["--once", "--map", m, "--map-geojson", g]), stderr=e, timeout=WAIT_S).returncode
    if rc != 0:
        fail("stemd without gpsd exited %d: %s" % (rc, tail(err)))
    log = open(err).read()
    if not re.search(r"gpsd 127\.0\.0\.1:%d: cannot connect: .*errno \d+\)" % port, log):
        fail("no log line naming gpsd's host:port and errno: " + tail(err))
    plants = map_lines(m)
    if not plants:
        fail("no plants in the map without gpsd")
    for p in plants:
        if p.get("georef") != "no_fix" or p.get("lat_deg", 0) is not None or p.get("lon_deg", 0) is not None:
            fail("a plant without a fix: " + json.dumps(p))
        if "s_mm" not in p or "y_mm" not in p:
            fail("field coordinates missing: " + json.dumps(p))
    doc = json.load(open(g))
    if len(doc["features"]) != len(plants) or any(f["geometry"] is not None for f in doc["features"]):
        fail("GeoJSON without fixes: %d features for %d plants, or a geometry" % (len(doc["features"]), len(plants)))
    print("without gpsd: %d plants, all georef no_fix with null coordinates" % len(plants))


def with_gpsfake(stemd, src, rec, tmp):
    port = free_port()
    m = os.path.join(tmp, "map.jsonl")
    g = os.path.join(tmp, "map.geojson")
    err = os.path.join(tmp, "stemd.err")
    with open(err, "w") as e:
        daemon = subprocess.Popen(stemd_args(stemd, src, rec, tmp, port,
                                             ["--set", "gnss.time=gnss", "--map", m, "--map-geojson", g]), stderr=e)
    procs = [("stemd", daemon, err)]
    fake = None
    try:
        pattern = re.compile(r"odometry: first frame captured at t_ns (\d+) \(CLOCK_MONOTONIC\), odometer ([-\d.]+) mm")
        found = wait_for("odometry start line from stemd", lambda: pattern.search(open(err).read()), procs=procs)
        t_capture = int(found.group(1))
        t0 = t_capture - float(found.group(2)) / SPEED_MM_PER_S * 1e9   # odometer 0 on CLOCK_MONOTONIC
        offset = clock_offset_ns()

        # The track: BoniRob's RTK track, tiled along its fitted line and
        # retimed so that its distance along the line equals the odometer.
        track = bonirob_track()
        ux, uy = track["u"]
        vx, vy = -uy, ux   # left of the track
        enu = gnss_nmea.Enu(*track["origin"])
        step = 10_000_000   # NMEA times have hundredths
        nmea = os.path.join(tmp, "track.nmea")
        first_utc = None
        with open(nmea, "w", newline="") as f:
            k = -2
            last_utc = 0
            while True:
                for d, c in zip(track["d"], track["c"]):
                    along_mm = (k * track["length"] + d) * 1e3
                    utc = int(round((t0 + along_mm / SPEED_MM_PER_S * 1e9 + offset) / step)) * step
                    if utc <= last_utc:
                        continue
                    prev_utc, last_utc = last_utc, utc
                    first_utc = utc if first_utc is None else first_utc
                    # Rounding the time moved the fix along the line (< 3 mm):
                    # it stays where the odometer is at that time.
                    along = (utc - offset - t0) * 1e-9 * SPEED_MM_PER_S * 1e-3
                    lat, lon, h = enu.to_geodetic(along * ux + c * vx, along * uy + c * vy, 0)
                    f.write(gnss_nmea.epoch(utc, lat, lon, h - 47.0, SPEED_MM_PER_S * 1e-3, track["course"],
                                            track["rms"]))
                k += 1
                if last_utc - offset - t0 > 90e9:
                    break
        utc_end = prev_utc
        fake_log = os.path.join(tmp, "gpsfake.log")
        with open(fake_log, "w") as fl:
            # -W: gpsfake lingers this long after the log (then exits 1):
            # it is stopped below, once the plants are in.
            # TMPDIR: gpsd's control socket goes into the scratch folder.
            fake = subprocess.Popen(["gpsfake", "-1", "-q", "-W", "600", "-P", str(port), "-c", "0.004",
                                     "-s", "115200", nmea], stdout=fl, stderr=subprocess.STDOUT,
                                    env=dict(os.environ, TMPDIR=tmp))
        procs.append(("gpsfake", fake, fake_log))
        # gpsfake feeds its pty from the start, client or not: what it fed
        # before stemd connected is lost. A watcher connected after stemd
        # sees no fix that stemd did not also see.
        wait_for("connection of stemd to gpsfake's gpsd",
                 lambda: re.search(r"gpsd 127\.0\.0\.1:%d: connected" % port, open(err).read()), procs=procs)
        watcher = GpsdWatcher(port)
        wait_for("a fix at the watcher", lambda: watcher.poll() and watcher.first_ns, procs=procs)
        # The whole log fed (gpsd may hold the last epoch back until the next).
        wait_for("the end of gpsfake's feed", lambda: watcher.poll() and watcher.last_ns >= utc_end, procs=procs)
        t_fed = time.clock_gettime_ns(time.CLOCK_MONOTONIC)
        watcher.close()
        # Plants whose track ended after that, with fixes around them (a
        # heading baseline) after the first the watcher saw, had every fix
        # there was.
        s_fed = max((t_fed + 1e9 - t0) * 1e-9 * SPEED_MM_PER_S,
                    (watcher.first_ns - offset - t0) * 1e-9 * SPEED_MM_PER_S + HEADING_BASELINE_MM)
        wait_for("%d plants past s_mm %.0f" % (MIN_PLANTS_AFTER_FEED, s_fed),
                 lambda: sum(p["s_mm"] > s_fed for p in map_lines(m)) >= MIN_PLANTS_AFTER_FEED, procs=procs[:1])
        # While it runs, the GeoJSON is rewritten every 30 s through a
        # rename: whenever it is there, it is a whole document.
        wait_for("the periodic GeoJSON", lambda: os.path.exists(g), procs=procs[:1])
        periodic = json.load(open(g))
        if periodic.get("type") != "FeatureCollection" or not periodic["features"]:
            fail("the periodic GeoJSON: %s with %d features" % (periodic.get("type"), len(periodic["features"])))
        daemon.send_signal(signal.SIGTERM)
        rc = daemon.wait(timeout=WAIT_S)
        if rc != 0:
            fail("stemd exited %d after SIGTERM: %s" % (rc, tail(err)))
    finally:
        for p in (daemon, fake):
            if p is not None and p.poll() is None:
                # SIGINT: gpsfake then stops its gpsd too.
                p.send_signal(signal.SIGINT)
                try:
                    p.wait(timeout=30)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()

    plants = map_lines(m)
    errors = []
    late = 0
    late_degraded = 0
    degraded = 0
    for p in plants:
        for key in ("lat_deg", "lon_deg", "georef"):
            if key not in p:
                fail("a map line without %s: %s" % (key, json.dumps(p)))
        if p["s_mm"] > s_fed:
            late += 1
            # Fixes all around it: placed between them. gpsd may report any
            # epoch before its GST (seen once beside a loaded host, not only
            # a session's first), and a plant placed from that report is
            # degraded: its eph is then checked below like every other.
            if p["georef"] not in ("fix", "degraded"):
                fail("a plant that ended after the whole track was fed is %s: %s" % (p["georef"], json.dumps(p)))
            late_degraded += p["georef"] == "degraded"
        # The log is RTK fixed (GGA quality 4) with a GST error of a few mm:
        # every placed plant says so. A gpsd report before its GST (a
        # session's first, mostly) estimates eph from the
        # DOP (metres): plants placed from that fix are degraded, the rest
        # are within the default gnss.max_eph_mm.
        if p["georef"] in ("fix", "extrapolated", "degraded"):
            if (p.get("gnss_mode") != "3d" or p.get("gnss_status") != "rtk_fixed"
                    or not isinstance(p.get("eph_mm"), (int, float))
                    or (p["eph_mm"] > 100) != (p["georef"] == "degraded")):
                fail("a placed plant without the log's fix quality: " + json.dumps(p))
            degraded += p["georef"] == "degraded"
        if p["georef"] not in ("fix", "extrapolated", "degraded"):
            if p["lat_deg"] is not None:
                fail("a position with georef %s: %s" % (p["georef"], json.dumps(p)))
            continue
        s_m = p["s_mm"] * 1e-3
        dx = (CAMERA_X_MM - ANTENNA_X_MM) * 1e-3
        dy = (p["y_mm"] - ANTENNA_Y_MM) * 1e-3
        true_e = s_m * ux + dx * ux - dy * uy
        true_n = s_m * uy + dx * uy + dy * ux
        e, n, _ = enu.to_enu(p["lat_deg"], p["lon_deg"], track["origin"][2])
        errors.append((math.hypot(e - true_e, n - true_n), p))
    if late < MIN_PLANTS_AFTER_FEED:
        fail("only %d plants after the feed" % late)
    errors.sort(key=lambda x: x[0])
    worst = errors[-1]
    print("gpsfake: %d plants, %d placed (%d degraded, %d after the whole track was fed, %d of them degraded); "
          "position error median %.1f mm, max %.1f mm (tolerance 20 mm + the track's %.1f mm)" % (
              len(plants), len(errors), degraded, late, late_degraded, errors[len(errors) // 2][0] * 1e3, worst[0] * 1e3,
              track["max_c"] * 1e3))
    tolerance = 0.020 + track["max_c"]
    if worst[0] > tolerance:
        fail("plant %s is %.1f mm from its true position" % (json.dumps(worst[1]), worst[0] * 1e3))
    if not re.search(r"fixes \(0 without a position, 0 dropped\), \d+ on the track", open(err).read()):
        fail("GNSS summary: " + tail(err))
    if not re.search(r"gnss: 3d rtk_fixed, eph [\d.]+ mm, fixes \d+, degraded %d" % degraded, open(err).read()):
        fail("no GNSS quality in the status: " + tail(err))

    # The GeoJSON, as a GIS reads it: RFC 7946 [lon, lat], one feature a plant.
    doc = json.load(open(g))
    if doc.get("type") != "FeatureCollection" or len(doc["features"]) != len(plants):
        fail("GeoJSON: %s with %d features for %d plants" % (doc.get("type"), len(doc["features"]), len(plants)))
    for f, p in zip(doc["features"], plants):
        props = f["properties"]
        for key in ("class", "treated", "reason", "leaves", "s_mm", "y_mm", "georef", "gnss_mode", "gnss_status",
                    "eph_mm"):
            if props.get(key) != p.get(key):
                fail("GeoJSON property %s: %r, the map says %r" % (key, props.get(key), p.get(key)))
        if p["lat_deg"] is None:
            if f["geometry"] is not None:
                fail("a geometry for a plant without a position")
            continue
        lon, lat = f["geometry"]["coordinates"]
        if f["geometry"]["type"] != "Point" or abs(lon - p["lon_deg"]) > 1e-9 or abs(lat - p["lat_deg"]) > 1e-9:
            fail("GeoJSON geometry %s, the map says %s, %s" % (f["geometry"], p["lat_deg"], p["lon_deg"]))
    if os.path.exists(g + ".tmp"):
        fail("the GeoJSON's temporary file was left behind")
    if shutil.which("ogrinfo"):
        info = subprocess.run(["ogrinfo", "-ro", "-al", "-so", g], capture_output=True, text=True)
        if info.returncode != 0 or "Feature Count: %d" % len(plants) not in info.stdout or "Point" not in info.stdout:
            fail("ogrinfo: %s %s" % (info.stdout, info.stderr))
        print("ogrinfo reads %d point features" % len(plants))


def main():
    if len(sys.argv) != 4:
        fail("usage: gnss_gpsfake.py STEMD TOOLS_DIR SOURCE_DIR")
    stemd, tools, src = sys.argv[1:]
    if not shutil.which("gpsfake") or not (shutil.which("gpsd") or os.path.exists("/usr/sbin/gpsd")):
        print("SKIP: gpsfake or gpsd not installed (apt install gpsd gpsd-clients)")
        return SKIP
    if "libgps" in subprocess.run([stemd, "--check-config", "--set", "gnss.source=gpsd"], capture_output=True,
                                text=True).stderr:
        print("SKIP: this stemd was built without libgps")
        return SKIP
    os.environ["PATH"] += os.pathsep + "/usr/sbin"
    with tempfile.TemporaryDirectory() as tmp:
        rec = os.path.join(tmp, "rec")
        subprocess.run([os.path.join(tools, "stemd-synth"), "--strip", "--out", rec, "--length-mm", "1500",
                        "--speed-kmh", "2", "--fps", "10", "--preset", "late", "--seed", "5"],
                       check=True, stdout=subprocess.DEVNULL)
        without_gpsd(stemd, src, rec, tmp)
        with_gpsfake(stemd, src, rec, tmp)
    return 0


if __name__ == "__main__":
    sys.exit(main())
