#!/usr/bin/env python3
"""WGS84 conversions and an NMEA 0183 writer (GGA, RMC, GST at each epoch, with
checksums) for the gpsfake test of the georeferenced plant map. Written
independently of src/geometry/georef.cpp, so that the test cross-checks it.
"""
import datetime
import math

A = 6378137.0
F = 1 / 298.257223563
E2 = F * (2 - F)


def geodetic_to_ecef(lat_deg, lon_deg, h):
    lat, lon = math.radians(lat_deg), math.radians(lon_deg)
    n = A / math.sqrt(1 - E2 * math.sin(lat) ** 2)
    return ((n + h) * math.cos(lat) * math.cos(lon), (n + h) * math.cos(lat) * math.sin(lon),
            (n * (1 - E2) + h) * math.sin(lat))


def ecef_to_geodetic(x, y, z):
    # Bowring's method followed by Newton steps on the latitude.
    p = math.hypot(x, y)
    lon = math.atan2(y, x)
    lat = math.atan2(z, p * (1 - E2))
    for _ in range(10):
        n = A / math.sqrt(1 - E2 * math.sin(lat) ** 2)
        h = p / math.cos(lat) - n
        lat = math.atan2(z, p * (1 - E2 * n / (n + h)))
    n = A / math.sqrt(1 - E2 * math.sin(lat) ** 2)
    return math.degrees(lat), math.degrees(lon), p / math.cos(lat) - n


class Enu:
    """A local east-north-up frame at an origin."""

    def __init__(self, lat_deg, lon_deg, h):
        self.o = geodetic_to_ecef(lat_deg, lon_deg, h)
        la, lo = math.radians(lat_deg), math.radians(lon_deg)
        self.sla, self.cla, self.slo, self.clo = math.sin(la), math.cos(la), math.sin(lo), math.cos(lo)

    def to_enu(self, lat_deg, lon_deg, h):
        x, y, z = geodetic_to_ecef(lat_deg, lon_deg, h)
        dx, dy, dz = x - self.o[0], y - self.o[1], z - self.o[2]
        return (-self.slo * dx + self.clo * dy,
                -self.sla * self.clo * dx - self.sla * self.slo * dy + self.cla * dz,
                self.cla * self.clo * dx + self.cla * self.slo * dy + self.sla * dz)

    def to_geodetic(self, e, n, u):
        x = self.o[0] - self.slo * e - self.sla * self.clo * n + self.cla * self.clo * u
        y = self.o[1] + self.clo * e - self.sla * self.slo * n + self.cla * self.slo * u
        z = self.o[2] + self.cla * n + self.sla * u
        return ecef_to_geodetic(x, y, z)


def checksum(body):
    c = 0
    for ch in body.encode("ascii"):
        c ^= ch
    return "%02X" % c


def sentence(body):
    return "$%s*%s\r\n" % (body, checksum(body))


def _lat(lat):
    d = int(abs(lat))
    return "%02d%010.7f,%s" % (d, (abs(lat) - d) * 60, "N" if lat >= 0 else "S")


def _lon(lon):
    d = int(abs(lon))
    return "%03d%010.7f,%s" % (d, (abs(lon) - d) * 60, "E" if lon >= 0 else "W")


def epoch(t_utc_ns, lat, lon, alt_msl, speed_mps, course_deg, err_m):
    """GGA (RTK fixed), RMC and GST for one fix at UTC t_utc_ns."""
    t = datetime.datetime.fromtimestamp(t_utc_ns // 1_000_000_000, datetime.timezone.utc)
    hundredths = (t_utc_ns % 1_000_000_000) // 10_000_000
    hms = "%02d%02d%02d.%02d" % (t.hour, t.minute, t.second, hundredths)
    dmy = "%02d%02d%02d" % (t.day, t.month, t.year % 100)
    gga = "GPGGA,%s,%s,%s,4,14,0.7,%.3f,M,47.000,M,1.0,0001" % (hms, _lat(lat), _lon(lon), alt_msl)
    rmc = "GPRMC,%s,A,%s,%s,%.3f,%.2f,%s,,,R" % (hms, _lat(lat), _lon(lon), speed_mps / 0.514444, course_deg % 360,
                                                 dmy)
    gst = "GPGST,%s,%.3f,%.3f,%.3f,0.0,%.3f,%.3f,%.3f" % (hms, err_m, err_m, err_m, err_m, err_m, 2 * err_m)
    return sentence(gga) + sentence(rmc) + sentence(gst)
