#!/usr/bin/python3
"""Where a predicted vegetation mask differs from the human one.

For every frame of a recording directory with a `mask` column, and the
masks `stemd-detect --mask-out MASKS` wrote for it, prints the IoU, the false
positives (FP) and false negatives (FN) as shares of the human vegetation
area, split by distance to the human outline (within 1 px, 1-2 px, beyond
2 px); the IoU with a band of 1 or 2 px around the human outline left out
(what the outline's placement costs); and the far errors (beyond 2 px) that
are dark (below the 10th percentile of the frame's vegetation brightness:
shadows, dark leaf parts) or specular (a channel at 235 or more). Then the
human components the prediction misses entirely (small plants), and the
means.

  tools/mask-errors.py RECORDING MASKS [--gt-vegetation nonzero|zero]

Needs python3-opencv and python3-numpy (Debian).
"""
import argparse
import os
import sys

import cv2
import numpy as np
from masked_frames import masked_rows


def frame_errors(bgr, truth, predicted):
    area = max(int(truth.sum()), 1)
    inside = cv2.distanceTransform(truth.astype(np.uint8), cv2.DIST_L2, 3)
    outside = cv2.distanceTransform((~truth).astype(np.uint8), cv2.DIST_L2, 3)
    distance = np.where(truth, inside, outside)  # to the human outline, px
    fp, fn = predicted & ~truth, truth & ~predicted

    def share(m):
        return float(m.sum()) / area

    def iou_without_band(px):
        keep = distance > px
        union = ((predicted | truth) & keep).sum()
        return float((predicted & truth & keep).sum()) / max(int(union), 1)

    brightness = bgr.astype(np.int32).sum(axis=2)
    dark = brightness < np.percentile(brightness[truth], 10) if truth.any() else np.zeros_like(truth)
    specular = bgr.max(axis=2) >= 235
    far = distance > 2
    labels_n, labels = cv2.connectedComponents(truth.astype(np.uint8), connectivity=8)
    hit = np.bincount(labels[predicted], minlength=labels_n)
    missed = [k for k in range(1, labels_n) if hit[k] == 0]
    missed_area = int(np.isin(labels, missed).sum()) if missed else 0
    union = max(int((predicted | truth).sum()), 1)
    return {
        "IoU": float((predicted & truth).sum()) / union,
        "FP": share(fp), "FN": share(fn),
        "FP<=1": share(fp & (distance <= 1)), "FP1-2": share(fp & (distance > 1) & (distance <= 2)),
        "FP>2": share(fp & far),
        "FN<=1": share(fn & (distance <= 1)), "FN1-2": share(fn & (distance > 1) & (distance <= 2)),
        "FN>2": share(fn & far),
        "IoU-1px": iou_without_band(1), "IoU-2px": iou_without_band(2),
        "farFPdark": share(fp & far & dark), "farFPspec": share(fp & far & specular & ~dark),
        "farFNdark": share(fn & far & dark), "farFNspec": share(fn & far & specular & ~dark),
        "missedComp": len(missed), "missedArea": missed_area / area,
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("recording")
    parser.add_argument("masks", help="stemd-detect --mask-out's folder (255 = vegetation)")
    parser.add_argument("--gt-vegetation", choices=["nonzero", "zero"], default="nonzero")
    args = parser.parse_args()
    rows = masked_rows(args.recording, "mask-errors")
    results = []
    for i, row in enumerate(rows):
        bgr = cv2.imread(os.path.join(args.recording, row["rgb"]), cv2.IMREAD_COLOR)
        mask = cv2.imread(os.path.join(args.recording, row["mask"]), cv2.IMREAD_GRAYSCALE)
        stem = os.path.splitext(os.path.basename(row["rgb"]))[0]
        pred = None
        for name in (stem + ".png", f"{i:04d}.png", f"{i:06d}.png"):
            pred = cv2.imread(os.path.join(args.masks, name), cv2.IMREAD_GRAYSCALE)
            if pred is not None:
                break
        if bgr is None or mask is None or pred is None or bgr.shape[:2] != mask.shape or pred.shape != mask.shape:
            sys.exit(f"mask-errors: {row['rgb']}: unreadable image, mask or prediction, or sizes differ")
        truth = mask > 0 if args.gt_vegetation == "nonzero" else mask == 0
        results.append((stem, frame_errors(bgr, truth, pred > 0)))
    keys = list(results[0][1])
    print("frame      " + " ".join(f"{k:>10}" for k in keys))
    for stem, r in results:
        print(f"{stem:10} " + " ".join(f"{r[k]:10.3f}" if k != "missedComp" else f"{r[k]:10d}" for k in keys))
    print("mean       " + " ".join(f"{np.mean([r[k] for _, r in results]):10.3f}" for k in keys))


if __name__ == "__main__":
    main()
