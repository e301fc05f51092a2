"""The frames of a recording that have a human mask, for the mask-study
scripts (iou-ceiling.py, mask-errors.py, outline-rules.py)."""
import csv
import os
import sys


def masked_rows(recording, tool):
    """frames.csv's rows with a mask column; exits naming TOOL and the file
    when it cannot be read or no frame has a mask."""
    listing = os.path.join(recording, "frames.csv")
    try:
        with open(listing, newline="") as f:
            rows = [row for row in csv.DictReader(f) if row.get("mask")]
    except OSError as e:
        sys.exit(f"{tool}: {listing}: {e.strerror}")
    if not rows:
        sys.exit(f"{tool}: {listing}: no frame with a mask")
    return rows
