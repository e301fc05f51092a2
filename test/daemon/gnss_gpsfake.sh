#!/usr/bin/env bash
# The georeferenced plant map end to end: gpsfake (Debian gpsd-clients)
# replays a generated NMEA track into a private gpsd; stemd replays a strip
# with gnss.source gpsd; every plant's latitude and longitude is checked
# against the track-projected truth (test/daemon/gnss_gpsfake.py).
#   gnss_gpsfake.sh STEMD TOOLS_DIR SOURCE_DIR
exec python3 "$3/test/daemon/gnss_gpsfake.py" "$@"
